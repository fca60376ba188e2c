#!/usr/bin/env bash
# ARPACK against SLEPc on 1 and 2 MPI ranks on the ~0.5M-unknown mould (docs/benchmarks.md):
# wall time, stage timings and peak resident memory per rank (GNU time).
# Needs a build with SLEPc: cargo build --release -p ves-pipeline --features slepc
set -euo pipefail
cd "$(dirname "$0")/.."
scene="${1:-bench/mould-p2.toml}"
out="${TMPDIR:-/tmp}/ves-slepc-scaling"
mkdir -p "$out"
ves="$PWD/target/release/ves"
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
run() { # name, command...
  local name="$1"; shift
  "$@" > "$out/$name.json" 2> "$out/$name.err" || { echo "$name failed:"; tail -3 "$out/$name.err"; return 1; }
  python3 - "$out/$name.json" "$out/$name.err" "$name" <<'PY'
import json, re, sys
d = json.loads(open(sys.argv[1]).read().strip().splitlines()[-1])
err = open(sys.argv[2]).read()
rss = [int(x) / 1e6 for x in re.findall(r"Maximum resident set size \(kbytes\): (\d+)", err)]
wall = re.findall(r"Elapsed \(wall clock\) time \(h:mm:ss or m:ss\): (\S+)", err)
t, s = d["timings_s"], d["spaces"][0]
print(f"| {sys.argv[3]} | {s['dofs']} | {t['mesh']:.1f} | {t['assemble']:.1f} | {t['factorize']:.1f} | {t['eigensolve']:.1f} | {t['total']:.1f} | {wall[0] if wall else '?'} | {' / '.join(f'{r:.2f}' for r in rss)} | {s['frequencies_hz'][0]:.6f} | {s['frequencies_hz'][-1]:.6f} |")
PY
}
echo "| solver | unknowns | mesh | assemble | factorize | eigensolve | total (s) | wall | peak RSS per rank (GB) | f1 (Hz) | f30 (Hz) |"
echo "|---|---|---|---|---|---|---|---|---|---|---|"
run arpack /usr/bin/time -v "$ves" precompute "$scene" -o "$out/arpack.h5" --solver arpack --json
run slepc-1 /usr/bin/time -v "$ves" precompute "$scene" -o "$out/slepc1.h5" --solver slepc --json
run slepc-2 mpirun -n 2 /usr/bin/time -v "$ves" precompute "$scene" -o "$out/slepc2.h5" --solver slepc --json
