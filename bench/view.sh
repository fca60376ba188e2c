#!/usr/bin/env bash
# Measures `ves view` on a basis (default: the mould, precomputed into bench/out if missing):
# pointer-to-frame latency, frames per second with 1 and 20 clients, server memory after 20
# clients vanish. Prints the browser side's JSON, then the server's statistics (ves view --json).
# usage: bench/view.sh [BASIS.h5]
set -euo pipefail
cd "$(dirname "$0")/.."
ves=target/release/ves
[ -x "$ves" ] || cargo build --release -p ves-cli >&2
basis=${1:-bench/out/mould.h5}
if [ ! -f "$basis" ]; then
  mkdir -p "$(dirname "$basis")"
  "$ves" precompute cases/mould/scene.toml -o "$basis" >&2
fi
log=$(mktemp)
"$ves" view "$basis" --port 0 --json > "$log" 2>&2 &
server=$!
trap 'kill -INT $server 2>/dev/null || true' EXIT
for _ in $(seq 100); do grep -q "http://" "$log" && break; sleep 0.1; done
url=$(grep -o "http://[^ ]*" "$log")
node bench/view.mjs "$url" "$server" view/web
kill -INT $server
wait $server || true
trap - EXIT
tail -n 1 "$log"
rm -f "$log"
