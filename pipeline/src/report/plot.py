"""Plots of a `ves report`: error against online and offline time, log axes, Pareto fronts.

Usage: python3 plot.py report.json OUTDIR  (writes error_vs_online.{png,svg}, error_vs_offline.{png,svg})
"""
import json
import os
import sys
import tempfile

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

UMASK = os.umask(0)
os.umask(UMASK)
report = json.load(open(sys.argv[1]))
out = sys.argv[2]
meshes = report["meshes"]
colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]


def worst(v):
    return max(v) if v else None


def pareto(points):
    """Points (x, y) not dominated by another (smaller x and smaller y), sorted by x."""
    pts = sorted(p for p in points if p[0] > 0 and p[1] is not None and p[1] > 0)
    front, best = [], float("inf")
    for x, y in pts:
        if y < best:
            front.append((x, y))
            best = y
    return front


# (title, value of a point, corrected variant or None)
panels = [
    ("frequency error vs finest mesh", lambda p: p["frequency_error"], None),
    ("point-load displacement error", lambda p: worst(p["static_error"]), lambda p: worst(p["static_error_corrected"])),
    (
        "point-load error vs finest mesh's full solve",
        lambda p: worst(p["static_error_total"]),
        lambda p: worst(p["static_error_total_corrected"]),
    ),
    ("step-load response error (RMS over time)", lambda p: worst(p["dynamic_error_rms"]), lambda p: worst(p["dynamic_error_rms_corrected"])),
]
axes_x = [
    ("online", "haptic step time (µs, median)", lambda m, p: p["haptic_step_ns"] / 1e3, lambda m, p: p["haptic_step_ns"] / 1e3),
    (
        "offline",
        "offline time (s): mesh + assemble + factorise + eigen-solve [+ static correction]",
        lambda m, p: p["offline_s"],
        lambda m, p: p["offline_with_correction_s"],
    ),
]
for name, xlabel, x_plain, x_corr in axes_x:
    fig, axs = plt.subplots(2, 2, figsize=(13, 10), constrained_layout=True)
    axs = axs.flatten()
    for ax, (title, y_plain, y_corr) in zip(axs, panels):
        series = [("", x_plain, y_plain, "o", True)]
        if y_corr is not None and not report["free_body"]:
            series.append((" + static corr.", x_corr, y_corr, "s", False))
        for label_suffix, xf, yf, marker, filled in series:
            allpts = []
            for i, m in enumerate(meshes):
                pts = [(xf(m, p), yf(p), p["modes"]) for p in m["points"]]
                pts = [q for q in pts if q[0] is not None and q[1] is not None and q[1] > 0]
                allpts += [(x, y) for x, y, _ in pts]
                if not pts:
                    continue
                c = colors[i % len(colors)]
                ax.scatter(
                    [q[0] for q in pts],
                    [q[1] for q in pts],
                    marker=marker,
                    facecolors=c if filled else "none",
                    edgecolors=c,
                    label=f"P{m['order']} h={m['size']:.4g} m{label_suffix}",
                )
                for x, y, r in pts:
                    ax.annotate(str(r), (x, y), textcoords="offset points", xytext=(3, 3), fontsize=7, color=c)
            front = pareto(allpts)
            if front:
                ax.plot([p[0] for p in front], [p[1] for p in front], "k--" if filled else "k:", lw=1,
                        label="Pareto front" + label_suffix)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(xlabel)
        ax.set_ylabel("relative error")
        ax.set_title(title)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle(f"{report['scene']}: error against {name} time (labels: number of modes)")
    for ext in ("png", "svg"):
        # A new file of our own (never a planted link), renamed when complete.
        fd, tmp = tempfile.mkstemp(dir=out, prefix=f".error_vs_{name}.", suffix=f".{ext}")
        try:
            os.chmod(tmp, 0o666 & ~UMASK)  # as any new file (mkstemp makes it private)
            with os.fdopen(fd, "wb") as f:
                fig.savefig(f, format=ext, dpi=110)
            os.replace(tmp, f"{out}/error_vs_{name}.{ext}")
        except BaseException:
            os.unlink(tmp)
            raise
    plt.close(fig)
