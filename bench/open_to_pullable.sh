#!/usr/bin/env bash
# The first compute `ves view PART.step` runs when a part is opened — the page's starting scene
# (a free body of structural steel, 10-node tets to a 5 % error estimate, 12 modes, stress) — timed
# as `ves precompute` of that scene with an empty mesh cache, for each part given (default: the
# shared corpus). The part is pullable when this basis is written, plus the page's load of it.
# Prints one JSON line per part: wall seconds, unknowns, meshes of the refinement, estimate.
# FIRST_LOOK=1: the page's first look instead (the first mesh of that refinement, 1/15 of the
# part's largest extent, solved without its estimate: what the page serves first when no mesh is
# remembered; its curved tets straightened without gmsh's smoother, as the page does), timed as
# `ves precompute` of that mesh with `error_estimate = false` — which still
# makes the Sturm count the page's first look leaves to later, so it is a little slower.
# usage: [FIRST_LOOK=1] bench/open_to_pullable.sh [PART.step ...]
set -euo pipefail
cd "$(dirname "$0")/.."
ves=${VES:-target/release/ves}
[ -x "$ves" ] || cargo build --release -p ves-cli >&2
parts=("$@")
[ ${#parts[@]} -gt 0 ] || parts=(../shared/geometry/corpus/*.step)
for part in "${parts[@]}"; do
  work=$(mktemp -d)
  cp "$part" "$work/part.step"
  cat > "$work/scene.toml" <<TOML
name = "part"
[geometry]
step = "part.step"
[material]
young = 2.1e11
poisson = 0.3
density = 7850.0
yield_strength = 2.5e8
[mesh]
order = 2
MESH_LINE
[modes]
count = 12
[stress]
enabled = true
[damping]
alpha = 0.0
beta = 1.0e-5
TOML
  if [ "${FIRST_LOOK:-}" = 1 ]; then
    # The first mesh's size, as VES advises it for a size larger than the part: 1/15 of its extent.
    sed 's/^MESH_LINE$/size = 1e3/' "$work/scene.toml" > "$work/probe.toml"
    size=$("$ves" precompute "$work/probe.toml" -o "$work/never.h5" 2>&1 | sed -n 's/.*use about \([0-9.e+-]*\) m.*/\1/p' | head -1 || true)
    sed -i "s/^MESH_LINE$/size = $size\nerror_estimate = false\nsmooth_curved = false/" "$work/scene.toml"
  else
    sed -i 's/^MESH_LINE$/target_error = 0.05/' "$work/scene.toml"
  fi
  start=$(date +%s.%N)
  if VES_CACHE_DIR="$work/cache" "$ves" precompute "$work/scene.toml" -o "$work/b.h5" --json > "$work/out.json" 2> "$work/err"; then
    end=$(date +%s.%N)
    python3 - "$part" "$start" "$end" "$work/out.json" <<'PY'
import json, sys
part, start, end, out = sys.argv[1:]
d = json.loads(open(out).read().strip().splitlines()[-1])
s = d["spaces"][0]
est = [e for e in (s.get("estimated_relative_error") or []) if e == e]
print(json.dumps({"part": part.rsplit("/", 1)[-1], "wall_s": round(float(end) - float(start), 2),
                  "unknowns": s["dofs"], "meshes": len(s.get("refinements") or []),
                  "estimate": max(est) if est else None, "mesh_s": round(d["timings_s"]["mesh"], 2)}))
PY
  else
    echo "{\"part\": \"$(basename "$part")\", \"error\": $(tail -1 "$work/err" | python3 -c 'import json,sys; print(json.dumps(sys.stdin.read().strip()))')}"
  fi
  rm -rf "$work"
done
