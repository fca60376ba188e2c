#!/usr/bin/env python3
"""How evenly `ves batch --shard K/N` splits a batch: a Markdown table.

    python3 bench/batch_shards.py [--shards 2,3,4] [--corpus DIR]

Builds a batch of real parts (the shared corpus's STEP files, free bodies of steel) in three
settings each — 4-node tets at 1/20 of the largest extent with 10 modes, 10-node tets at 1/12
with 20 modes, 4-node at 1/35 with 30 modes — and times every scene once, one at a time, with an
empty mesh cache (`ves batch -j 1 --json`, each scene's `seconds`). Then, for each shard count
N, the shards `ves batch --status --shard 1/N --json` assigns (the split by expected cost every
node computes alike) are set beside a split by count (every N-th scene in the agreed order) and
the ideal (the larger of the total over N and the longest scene): the time each split's slowest
shard would take, from the measured scene times. "With taking" simulates what `ves batch` does
by default — a shard done with its share takes the scenes other shards have not started, the
last of their lists first — as if every shard had a node of its own. Also the rank correlation
of the expected costs with the measured times, and each scene's cost and time.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# Largest extents, mm (SOURCES.md); the thin cone does not mesh at every size (a PLC error).
PARTS = {
    "flange_io1": 88.0, "pmi_block_2holes": 20.0, "bracket_ribbed_ap209": 146.5,
    "crankshaft": 63.0, "control_arm": 244.9, "cylinder_head_fins": 29.1,
    "cast_housing_b2": 110.5, "soapbox_shell": 128.0, "engine_block": 54.0,
}
SETTINGS = [("p1", 1, 20, 10), ("p2", 2, 12, 20), ("p1fine", 1, 35, 30)]


def ranks(xs):
    order = sorted(range(len(xs)), key=lambda i: xs[i])
    r = [0] * len(xs)
    for k, i in enumerate(order):
        r[i] = k
    return r


def spearman(a, b):
    ra, rb = ranks(a), ranks(b)
    n = len(a)
    return 1 - 6 * sum((x - y) ** 2 for x, y in zip(ra, rb)) / (n * (n * n - 1))


def with_taking(t, cost, shard, n):
    """Makespan when each shard does its list (costliest first), then takes others' unstarted
    scenes from the ends of their lists, round by round."""
    lists = [sorted([i for i in range(len(t)) if shard[i] == k + 1], key=lambda i: -cost[i]) for k in range(n)]
    started, clock = set(), [0.0] * n
    while len(started) < len(t):
        k = min(range(n), key=lambda j: clock[j])
        own = [i for i in lists[k] if i not in started]
        if own:
            pick = own[0]
        else:
            pick = None
            for back in range(1, max(len(l) for l in lists) + 1):
                for j in range(n):
                    if j != k and back <= len(lists[j]) and lists[j][-back] not in started:
                        pick = lists[j][-back]
                        break
                if pick is not None:
                    break
        if pick is None:
            clock[k] = float("inf")
            continue
        started.add(pick)
        clock[k] += t[pick]
    return max(c for c in clock if c != float("inf"))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--shards", default="2,3,4")
    ap.add_argument("--corpus", default=os.path.join(ROOT, "../shared/geometry/corpus"))
    ap.add_argument("--ves", default=os.path.join(ROOT, "target/release/ves"))
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as work:
        scenes, out = os.path.join(work, "scenes"), os.path.join(work, "out")
        os.makedirs(scenes)
        for part, extent_mm in PARTS.items():
            step = os.path.abspath(os.path.join(a.corpus, part + ".step"))
            for tag, order, per, modes in SETTINGS:
                size = extent_mm / per / 1000.0
                open(os.path.join(scenes, f"{part}-{tag}.toml"), "w").write(
                    f'name = "{part}-{tag}"\n[geometry]\nstep = "{step}"\nunit = "mm"\n'
                    "[material]\nyoung = 2.1e11\npoisson = 0.3\ndensity = 7850.0\n"
                    f"[mesh]\nsize = {size:.6g}\norder = {order}\n[modes]\ncount = {modes}\n"
                )
        env = dict(os.environ, XDG_CACHE_HOME=os.path.join(work, "cache"), VES_LOG="error")
        run = subprocess.run([a.ves, "batch", scenes, "--out", out, "-j", "1", "--json"],
                             capture_output=True, text=True, env=env)
        outcomes = json.loads(run.stdout.strip().splitlines()[-1])
        seconds = {os.path.basename(o["scene"]): o["seconds"] for o in outcomes if o["status"] == "done"}
        for o in outcomes:
            if o["status"] != "done":
                print(f"not timed: {os.path.basename(o['scene'])}: {o['error']}", file=sys.stderr)
        rows = []
        corr = None
        for n in [int(x) for x in a.shards.split(",")]:
            st = subprocess.run([a.ves, "batch", scenes, "--out", out, "--status", "--json", "--shard", f"1/{n}"],
                                capture_output=True, text=True, env=env)
            states = [s for s in json.loads(st.stdout.strip().splitlines()[-1])["scenes"]
                      if os.path.basename(s["scene"]) in seconds]
            t = [seconds[os.path.basename(s["scene"])] for s in states]
            cost = [s["expected_cost"] for s in states]
            corr = spearman(cost, t)
            by_cost = [sum(x for x, s in zip(t, states) if s["shard"] == k) for k in range(1, n + 1)]
            by_count = [sum(x for i, x in enumerate(t) if i % n == k) for k in range(n)]
            ideal = max(sum(t) / n, max(t))
            taking = with_taking(t, cost, [s["shard"] for s in states], n)
            rows.append((n, len(t), sum(t), max(by_cost), taking, max(by_count), ideal))
            detail = [(os.path.basename(s["scene"])[:-5], c, x) for s, c, x in zip(states, cost, t)]
    print(f"{len(seconds)} scenes timed one at a time, {sum(seconds.values()):.1f} s in all; "
          f"rank correlation of expected cost with time: {corr:.2f}; load average {os.getloadavg()[0]:.1f}\n")
    print("| shards | slowest shard: split by expected cost (s) | the same, with taking (s) | split by count (s) | ideal (s) | with taking / ideal |")
    print("|---|---|---|---|---|---|")
    for n, k, total, c, take, cnt, ideal in rows:
        print(f"| {n} | {c:.1f} | {take:.1f} | {cnt:.1f} | {ideal:.1f} | {take / ideal:.2f} |")
    print("\n| scene | expected cost | seconds |\n|---|---|---|")
    for name, c, x in sorted(detail, key=lambda d: -d[1]):
        print(f"| {name} | {c:.3g} | {x:.1f} |")


if __name__ == "__main__":
    main()
