#!/usr/bin/env python3
"""Cost of one haptic step called from Python (`ves.Haptics.step`) against the same step in
Rust alone (the loop of `ves bench`), on one basis: median ns per step over batches of 1000.

    python3 bench/python_step.py BASIS.h5 [--modes 30] [--batches 200]

Both loops grab the first surface vertex and move the hand ±0.5 mm along z (button held), the
motion `ves bench` times; the Python loop writes the new position into one numpy array.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import ves


def median_ns(batches: int, per_batch: int, step) -> float:
    samples = []
    k = 0
    for _ in range(batches):
        t = time.perf_counter_ns()
        for _ in range(per_batch):
            k += 1
            step(k)
        samples.append((time.perf_counter_ns() - t) / per_batch)
    return float(np.median(samples))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("basis")
    ap.add_argument("--modes", type=int, default=30)
    ap.add_argument("--batches", type=int, default=200)
    a = ap.parse_args()
    basis = ves.Basis.open(a.basis)
    r = min(a.modes, basis.eigenvalues.shape[0])
    rust = ves._native._rust_step_ns(basis, modes=r, batches=a.batches, per_batch=1000)

    sim = ves.Haptics(basis, modes=r)
    p = sim.rest_positions[0].copy()
    hip = p[None, :].copy()

    def numpy_step(k: int) -> None:
        hip[0, 2] = p[2] + 1e-3 * ((k % 1000) / 1000.0 - 0.5)
        sim.step(hip, buttons=True)

    def list_step(k: int) -> None:
        sim.step([[p[0], p[1], p[2] + 1e-3 * ((k % 1000) / 1000.0 - 0.5)]], buttons=True)

    forces = np.zeros((1, 3))

    def out_step(k: int) -> None:
        hip[0, 2] = p[2] + 1e-3 * ((k % 1000) / 1000.0 - 0.5)
        sim.step(hip, None, True, forces)  # positional: no keyword dict to build

    def call_only(k: int) -> None:
        sim.time  # one attribute read: the floor of any call into the extension

    py_numpy = median_ns(a.batches, 1000, numpy_step)
    py_out = median_ns(a.batches, 1000, out_step)
    py_list = median_ns(a.batches, 1000, list_step)
    floor = median_ns(a.batches, 1000, call_only)
    nv = sim.rest_positions.shape[0]
    print(f"basis {a.basis}: {nv} surface vertices, r = {r} modes")
    print("| step | median ns | over Rust |")
    print("|---|---:|---:|")
    print(f"| Rust (`Haptics::step`, as `ves bench`) | {rust:.0f} | — |")
    print(f"| Python, numpy (1, 3) array in, new forces array out (`buttons=True`) | {py_numpy:.0f} | +{py_numpy - rust:.0f} |")
    print(f"| Python, numpy array in, forces into one reused array (`out`), positional arguments | {py_out:.0f} | +{py_out - rust:.0f} |")
    print(f"| Python, nested list in | {py_list:.0f} | +{py_list - rust:.0f} |")
    print(f"| Python, read `sim.time` only (no step) | {floor:.0f} | — |")


if __name__ == "__main__":
    main()
