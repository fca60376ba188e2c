#!/usr/bin/env python3
"""Kills and full disks while VES writes, and what they leave: every output pair must be the
old pair (basis + XDMF sidecar as before the run) or the new pair, never a mix, a half-written
file, or a corrupt basis behind an exit status of 0.

    python3 bench/fault_injection.py --ves target/release/ves --kills 40 --full 40 [--seed 1]

Precompute: a 'before' pair is written from scene A (4 modes), then each trial runs scene B
(3 modes) onto it and either kills it (SIGKILL) at a uniformly random time within its measured
run time, or limits the size any file may reach to a uniformly random number of bytes below the
new basis's size (RLIMIT_FSIZE with SIGXFSZ ignored: writes past it fail with EFBIG, as ENOSPC
does on a full disk). When run as root, a further M runs write into a small tmpfs filled to a
random number of free bytes (real ENOSPC). Batch: three scenes, the same kills. After each trial
the pair is classified against the old and the new reference (bytes of the old pair; the new
pair's sidecar bytes and its `ves info` frequencies); the next run must then succeed (a killed
run's temporaries are removed, a stale sidecar repaired). Prints a Markdown table.
"""
import argparse
import json
import os
import random
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
STEP = os.path.join(HERE, "..", "cases", "cantilever", "cantilever.step")
SCENE = """name = "{name}"
[geometry]
step = "beam.step"
unit = "mm"
[material]
young = 2.1e11
poisson = 0.3
density = 7850.0
[mesh]
size = 0.05
order = 1
[[fixed]]
plane = {{ axis = "x", value = 0.0 }}
[modes]
count = {count}
"""


def run(cmd, env, limit=None, kill_after=None):
    def pre():
        if limit is not None:
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
            resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
    p = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, preexec_fn=pre)
    if kill_after is not None:
        try:
            out, err = p.communicate(timeout=kill_after)
        except subprocess.TimeoutExpired:
            p.send_signal(signal.SIGKILL)
            out, err = p.communicate()
    else:
        out, err = p.communicate()
    return p.returncode, out.decode(errors="replace"), err.decode(errors="replace")


def read(path):
    try:
        with open(path, "rb") as f:
            return f.read()
    except OSError:
        return None


def frequencies(ves, env, basis):
    rc, out, _ = run([ves, "info", basis, "--json"], env)
    if rc != 0:
        return None
    return [s["frequencies_hz"] for s in json.loads(out)["spaces"]]


def classify(ves, env, h5, old, new):
    """'old', 'new' or what is wrong with the pair at h5 (+ .xdmf)."""
    xdmf = h5[:-3] + ".xdmf"
    pair = (read(h5), read(xdmf))
    if pair == old["bytes"]:
        return "old"
    if pair[1] == new["xdmf"] and frequencies(ves, env, h5) == new["freqs"]:
        return "new"
    if pair[0] == old["bytes"][0]:
        return "old basis, other sidecar"
    if frequencies(ves, env, h5) == new["freqs"]:
        return "new basis, other sidecar"
    return "basis neither old nor new"


def leftovers(d, keep):
    return sorted(set(os.listdir(d)) - set(keep))


def reference(ves, env, work, name, count):
    d = tempfile.mkdtemp(dir=work)
    shutil.copy(STEP, os.path.join(d, "beam.step"))
    scene = os.path.join(d, "s.toml")
    with open(scene, "w") as f:
        f.write(SCENE.format(name=name, count=count))
    h5 = os.path.join(d, name + ".h5")
    t = time.monotonic()
    rc, _, err = run([ves, "precompute", scene, "-o", h5], env)
    if rc != 0:
        sys.exit(f"reference run failed: {err}")
    return {
        "bytes": (read(h5), read(h5[:-3] + ".xdmf")),
        "xdmf": read(h5[:-3] + ".xdmf"),
        "freqs": frequencies(ves, env, h5),
        "seconds": time.monotonic() - t,
        "size": os.path.getsize(h5),
    }


def trial_dir(work, name, old_pair):
    d = tempfile.mkdtemp(dir=work)
    shutil.copy(STEP, os.path.join(d, "beam.step"))
    with open(os.path.join(d, "s.toml"), "w") as f:
        f.write(SCENE.format(name=name, count=3))
    h5 = os.path.join(d, name + ".h5")
    with open(h5, "wb") as f:
        f.write(old_pair[0])
    with open(h5[:-3] + ".xdmf", "wb") as f:
        f.write(old_pair[1])
    return d, h5


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--ves", default=os.path.join(HERE, "..", "target", "release", "ves"))
    ap.add_argument("--kills", type=int, default=40)
    ap.add_argument("--full", type=int, default=40)
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args()
    rng = random.Random(a.seed)
    ves = os.path.abspath(a.ves)
    work = tempfile.mkdtemp(prefix="ves-faults-")
    env = dict(os.environ, VES_CACHE_DIR=os.path.join(work, "cache"))
    old = reference(ves, env, work, "beam", 4)
    new = reference(ves, env, work, "beam", 3)
    # The mesh is cached now: runs are as long as the reference's rerun.
    new["seconds"] = reference(ves, env, work, "beam", 3)["seconds"]
    rows = []

    def tally(kind, outcomes, exits, rerun_ok):
        counts = {}
        for o in outcomes:
            counts[o] = counts.get(o, 0) + 1
        bad = sum(v for k, v in counts.items() if k not in ("old", "new"))
        rows.append((kind, len(outcomes), counts.get("old", 0), counts.get("new", 0), bad, exits, rerun_ok))

    # Kills during precompute.
    outcomes, reruns = [], 0
    for _ in range(a.kills):
        d, h5 = trial_dir(work, "beam", old["bytes"])
        run([ves, "precompute", os.path.join(d, "s.toml"), "-o", h5], env, kill_after=rng.uniform(0, new["seconds"]))
        outcomes.append(classify(ves, env, h5, old, new))
        rc, _, _ = run([ves, "precompute", os.path.join(d, "s.toml"), "-o", h5], env)
        reruns += rc == 0 and classify(ves, env, h5, old, new) == "new" and leftovers(d, ["beam.step", "s.toml", "beam.h5", "beam.xdmf"]) == []
        shutil.rmtree(d)
    tally("precompute, SIGKILL at a random time", outcomes, "-", f"{reruns}/{a.kills}")

    # Size limits during precompute.
    outcomes, zero_exits, reruns = [], 0, 0
    for _ in range(a.full):
        d, h5 = trial_dir(work, "beam", old["bytes"])
        limit = rng.randrange(0, new["size"])
        rc, _, _ = run([ves, "precompute", os.path.join(d, "s.toml"), "-o", h5], env, limit=limit)
        zero_exits += rc == 0
        outcomes.append(classify(ves, env, h5, old, new))
        reruns += leftovers(d, ["beam.step", "s.toml", "beam.h5", "beam.xdmf"]) == []
        shutil.rmtree(d)
    tally("precompute, file size limit at a random byte", outcomes, f"{zero_exits} exit 0", f"{reruns}/{a.full} no temporary left")

    # Real ENOSPC on a small tmpfs (root only).
    if os.geteuid() == 0 and a.full:
        mnt = os.path.join(work, "tmpfs")
        os.mkdir(mnt)
        if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=4m", "tmpfs", mnt]).returncode == 0:
            try:
                outcomes, zero_exits, reruns = [], 0, 0
                for _ in range(a.full):
                    for f in os.listdir(mnt):
                        os.remove(os.path.join(mnt, f))
                    shutil.copy(STEP, os.path.join(mnt, "beam.step"))
                    with open(os.path.join(mnt, "s.toml"), "w") as f:
                        f.write(SCENE.format(name="beam", count=3))
                    h5 = os.path.join(mnt, "beam.h5")
                    for p, b in zip((h5, h5[:-3] + ".xdmf"), old["bytes"]):
                        with open(p, "wb") as f:
                            f.write(b)
                    st = os.statvfs(mnt)
                    free = st.f_bavail * st.f_frsize
                    want = rng.randrange(0, 2 * new["size"])
                    with open(os.path.join(mnt, "filler"), "wb") as f:
                        f.write(b"\0" * max(0, free - want))
                    rc, _, _ = run([ves, "precompute", os.path.join(mnt, "s.toml"), "-o", h5], env)
                    os.remove(os.path.join(mnt, "filler"))
                    kind = classify(ves, env, h5, old, new)
                    zero_exits += rc == 0 and kind != "new"
                    outcomes.append(kind)
                    reruns += leftovers(mnt, ["beam.step", "s.toml", "beam.h5", "beam.xdmf"]) == []
                tally("precompute, tmpfs with random free bytes (ENOSPC)", outcomes, f"{zero_exits} exit 0 without the new pair", f"{reruns}/{a.full} no temporary left")
            finally:
                subprocess.run(["umount", mnt])

    # Kills during batch (three scenes, two jobs).
    outcomes, reruns = [], 0
    for _ in range(a.kills):
        d = tempfile.mkdtemp(dir=work)
        shutil.copy(STEP, os.path.join(d, "beam.step"))
        names = ["b1", "b2", "b3"]
        for n in names:
            with open(os.path.join(d, n + ".toml"), "w") as f:
                f.write(SCENE.format(name="beam", count=3).replace('"beam"\n', f'"{n}"\n', 1))
        out = os.path.join(d, "out")
        os.mkdir(out)
        for n in names:
            for ext, b in zip((".h5", ".xdmf"), old["bytes"]):
                with open(os.path.join(out, n + ext), "wb") as f:
                    f.write(b)
        run([ves, "batch", d, "--out", out, "-j", "2"], env, kill_after=rng.uniform(0, 2 * new["seconds"]))
        # The basis names its sidecar by file name: compare against references under each name.
        for n in names:
            nn = dict(new, xdmf=new["xdmf"].replace(b"beam.h5", f"{n}.h5".encode()))
            outcomes.append(classify(ves, env, os.path.join(out, n + ".h5"), old, nn))
        rc, _, _ = run([ves, "batch", d, "--out", out], env)
        reruns += rc == 0 and leftovers(out, [n + e for n in names for e in (".h5", ".xdmf")]) == []
        shutil.rmtree(d)
    tally("batch of 3, SIGKILL at a random time", outcomes, "-", f"{reruns}/{a.kills}")

    print(f"`{' '.join(sys.argv)}` (seed {a.seed}); old pair: 4 modes, new pair: 3 modes, cantilever 50 mm tets\n")
    print("| faults | outputs | old pair | new pair | anything else | exit status | next run / temporaries |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        print("| " + " | ".join(str(x) for x in r) + " |")
    shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
