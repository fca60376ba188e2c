#!/usr/bin/env bash
# Opening each part in the page as a user does (bench/open_in_page.mjs: `ves view PART.step`,
# empty mesh cache, no project, the page's WebSocket protocol): seconds to the first pullable
# basis (the first look) and to the converged one. One JSON line per part.
# usage: bench/open_in_page.sh [SECONDS_PER_PART] [PART.step ...]   (default: 90 s, the shared corpus)
set -euo pipefail
cd "$(dirname "$0")/.."
ves=${VES:-target/release/ves}
[ -x "$ves" ] || cargo build --release -p ves-cli >&2
limit=${1:-90}
shift || true
parts=("$@")
[ ${#parts[@]} -gt 0 ] || parts=(../shared/geometry/corpus/*.step)
for part in "${parts[@]}"; do
  node bench/open_in_page.mjs "$ves" "$part" view/web "$limit"
done
