#!/usr/bin/env bash
# ARPACK against SLEPc on 1, 2 and 4 MPI ranks on the ~0.5M-unknown mould (docs/benchmarks.md,
# docs/cluster.md): wall time, stage timings and peak resident memory per rank, rank 0 first
# (GNU time, one file per rank). 4 ranks on a 2-core machine are oversubscribed: their memory is
# what they are run for, not their time. Needs a build with SLEPc:
#   cargo build --release -p ves-cli --features slepc
set -euo pipefail
cd "$(dirname "$0")/.."
scene="${1:-bench/mould-p2.toml}"
out="${TMPDIR:-/tmp}/ves-slepc-scaling"
mkdir -p "$out"
ves="$PWD/target/release/ves"
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_plm=isolated
timed="$PWD/bench/time_rank.sh"
run() { # name, launcher..., -- ves args...
  local name="$1"; shift
  rm -f "$out/$name".rank*
  "$@" > "$out/$name.json" 2> "$out/$name.err" || { echo "$name failed:"; tail -3 "$out/$name.err"; return 1; }
  python3 - "$out" "$name" <<'PY'
import glob, json, re, sys
out, name = sys.argv[1], sys.argv[2]
d = json.loads(open(f"{out}/{name}.json").read().strip().splitlines()[-1])
ranks = sorted(glob.glob(f"{out}/{name}.rank*"), key=lambda p: int(p.rsplit("rank", 1)[1]))
text = [open(p).read() for p in ranks]
rss = [int(re.search(r"Maximum resident set size \(kbytes\): (\d+)", t).group(1)) / 1e6 for t in text]
wall = re.search(r"Elapsed \(wall clock\) time \(h:mm:ss or m:ss\): (\S+)", text[0]).group(1)
t, s = d["timings_s"], d["spaces"][0]
print(f"| {name} | {s['dofs']} | {t['mesh']:.1f} | {t['assemble']:.1f} | {t['factorize']:.1f} | {t['eigensolve']:.1f} | {t['total']:.1f} | {wall} | {' / '.join(f'{r:.2f}' for r in rss)} | {s['frequencies_hz'][0]:.6f} | {s['frequencies_hz'][-1]:.6f} |")
PY
}
echo "| solver | unknowns | mesh | assemble | factorize | eigensolve | total (s) | wall | peak RSS per rank, rank 0 first (GB) | f1 (Hz) | f30 (Hz) |"
echo "|---|---|---|---|---|---|---|---|---|---|---|"
run arpack "$timed" "$out/arpack" "$ves" precompute "$scene" -o "$out/arpack.h5" --solver arpack --json --force
run slepc-1 "$timed" "$out/slepc-1" "$ves" precompute "$scene" -o "$out/slepc1.h5" --solver slepc --json --force
run slepc-2 mpirun -n 2 "$timed" "$out/slepc-2" "$ves" precompute "$scene" -o "$out/slepc2.h5" --solver slepc --json --force
run slepc-4 mpirun -n 4 --oversubscribe "$timed" "$out/slepc-4" "$ves" precompute "$scene" -o "$out/slepc4.h5" --solver slepc --json --force
