#!/usr/bin/env bash
# `ves precompute` beside CalculiX on the same mesh, in one run (docs/benchmarks.md, issue 17).
#
# usage: bench/precompute_vs_calculix.sh SCENE.toml [SOLVER...]   (default solvers: auto arpack)
#
# For each solver: one precompute with an empty mesh cache (meshing included) and one on the
# cached mesh; the stage timings and peak memory come from `--json`. Then CalculiX: `ves verify
# --against calculix` writes the very same mesh as a C3D4/C3D10 deck (VES_KEEP_VERIFY keeps it)
# and its *FREQUENCY step is timed alone with `ccx` on 2 threads. Prints one JSON object per line.
set -euo pipefail
scene=$1
shift
solvers=("${@:-auto}")
[ $# -eq 0 ] && solvers=(auto arpack)
here=$(cd "$(dirname "$0")/.." && pwd)
ves=${VES:-$here/target/release/ves}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
export VES_CACHE_DIR=$work/cache

summary() { # label, json file, wall seconds
    python3 - "$1" "$2" "$3" <<'EOF'
import json, sys
label, path, wall = sys.argv[1], sys.argv[2], float(sys.argv[3])
d = json.load(open(path))
s = d["spaces"][0]
t = {k: round(v, 3) for k, v in d["timings_s"].items() if v >= 0.0005}
print(json.dumps({"run": label, "wall_s": round(wall, 2), "unknowns": s["dofs"], "modes": len(s["frequencies_hz"]),
                  "timings_s": t, "peak_rss_mb": round(d["peak_rss_bytes"] / 2**20),
                  "max_relative_residual": s["max_relative_residual"], "sturm_count": s.get("sturm_count"),
                  "f1_hz": s["frequencies_hz"][0], "f_last_hz": s["frequencies_hz"][-1]}))
EOF
}

for solver in "${solvers[@]}"; do
    rm -rf "$VES_CACHE_DIR"
    for run in cold cached; do
        t0=$(date +%s.%N)
        "$ves" precompute "$scene" -o "$work/basis.h5" --solver "$solver" --json > "$work/out.json" 2> "$work/err.txt" \
            || { cat "$work/err.txt" >&2; exit 1; }
        t1=$(date +%s.%N)
        summary "$solver, mesh $run" "$work/out.json" "$(echo "$t1 - $t0" | bc)"
    done
done

# CalculiX on the mesh of the last basis (the cached one: the same nodes and tets).
VES_KEEP_VERIFY=1 "$ves" verify "$work/basis.h5" --against calculix --json > "$work/verify.json" 2> "$work/verify.err" || true
dir=$(sed -n 's/^reference files kept in //p' "$work/verify.err")
# Into our own folder at once: another ves process on the machine removes the work folders of
# processes that have ended, and the verify that kept this one has.
[ -n "$dir" ] && cp -r "$dir" "$work/reference" && rm -rf "$dir"
deck=$(find "$work/reference" -name modes.inp 2>/dev/null | head -1)
[ -n "$deck" ] || { echo "no CalculiX deck: $(tail -3 "$work/verify.err")" >&2; exit 1; }
cd "$(dirname "$deck")"
rm -f modes.dat modes.frd
t0=$(date +%s.%N)
OMP_NUM_THREADS=2 CCX_NPROC_EQUATION_SOLVER=2 ccx -i modes > ccx.log 2>&1
t1=$(date +%s.%N)
python3 - "$(echo "$t1 - $t0" | bc)" "$work/verify.json" <<'EOF'
import json, sys
wall = float(sys.argv[1])
v = json.load(open(sys.argv[2]))
r = v["references"][0]
print(json.dumps({"run": "calculix *FREQUENCY alone, 2 threads", "wall_s": round(wall, 2),
                  "max_rel_freq_diff_vs_ves": r["max_rel_freq_diff"], "min_mac": r["min_mac_isolated"]}))
EOF
