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


# Older report.json files have none of these fields: nothing exact, flagged or banded then.
EXACT = report.get("exact_below", 0.0)
checks = report.get("probe_checks", [])
flagged = [k for k, c in enumerate(checks) if c.get("flagged")]


def worst(v):
    return max(v) if v else None


def worst_kept(v):
    """The worst over the probes that are not flagged (the "vs finest" panel)."""
    return worst([x for k, x in enumerate(v) if k not in flagged])


def pareto(points):
    """Points (x, y, lo, hi) not dominated, sorted by x. Another point dominates when it is more
    accurate and no dearer: its x is smaller, or its noise band [lo, hi] reaches below this one's
    upper end (a tie in time)."""
    pts = [p for p in points if p[0] > 0 and p[1] is not None and p[1] > 0]
    front = [
        p
        for p in pts
        if not any(q[1] < p[1] and (q[0] <= p[0] or q[2] <= p[3]) for q in pts if q is not p)
    ]
    return sorted(front)


# (title, value of a point, corrected variant or None)
panels = [
    ("frequency error vs finest mesh", lambda p: p["frequency_error"], None),
    ("probe-load displacement error (contact patch)", lambda p: worst(p["static_error"]), lambda p: worst(p["static_error_corrected"])),
    (
        "probe-load error vs finest mesh's full solve",
        lambda p: worst_kept(p["static_error_total"]),
        lambda p: worst_kept(p["static_error_total_corrected"]),
    ),
    ("step-load response error (RMS over time)", lambda p: worst(p["dynamic_error_rms"]), lambda p: worst(p["dynamic_error_rms_corrected"])),
]
axes_x = [
    (
        "online",
        "haptic step time (µs, median; bars: p25–p75 of the timed batches)",
        lambda m, p: p["haptic_step_ns"] / 1e3,
        lambda m, p: p["haptic_step_ns"] / 1e3,
    ),
    (
        "offline",
        "offline time (s): mesh + assemble + factorise + eigen-solve [+ static correction]",
        lambda m, p: p["offline_s"],
        lambda m, p: p["offline_with_correction_s"],
    ),
]


def noise(name, p, x):
    """The point's time band (lo, hi) on the x axis: p25–p75 online, none offline."""
    if name == "online" and "haptic_step_ns_p25" in p:
        return p["haptic_step_ns_p25"] / 1e3, p["haptic_step_ns_p75"] / 1e3
    return x, x


for name, xlabel, x_plain, x_corr in axes_x:
    fig, axs = plt.subplots(2, 2, figsize=(13, 10), constrained_layout=True)
    axs = axs.flatten()
    for ax, (title, y_plain, y_corr) in zip(axs, panels):
        series = [("", x_plain, y_plain, "o", True)]
        if y_corr is not None and not report["free_body"]:
            series.append((" + static corr.", x_corr, y_corr, "s", False))
        notes = []
        if "vs finest" in title and flagged:
            notes.append("left out (flagged, see the probe table): probe " + ", ".join(str(k + 1) for k in flagged))
        for label_suffix, xf, yf, marker, filled in series:
            allpts = []
            exact = 0
            for i, m in enumerate(meshes):
                pts = [(xf(m, p), yf(p), p["modes"], p) for p in m["points"]]
                pts = [q for q in pts if q[0] is not None and q[1] is not None]
                # Exact values (zero up to rounding) would stretch the log axis over decades of noise.
                exact += sum(1 for q in pts if q[1] <= EXACT)
                pts = [q for q in pts if q[1] > EXACT and q[1] > 0]
                allpts += [(x, y) + noise(name, p, x) for x, y, _, p in pts]
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
                if name == "online" and filled:
                    bands = [noise(name, p, x) for x, _, _, p in pts]
                    ax.errorbar(
                        [q[0] for q in pts],
                        [q[1] for q in pts],
                        xerr=[[max(q[0] - b[0], 0) for q, b in zip(pts, bands)], [max(b[1] - q[0], 0) for q, b in zip(pts, bands)]],
                        fmt="none",
                        ecolor=c,
                        elinewidth=0.8,
                        alpha=0.6,
                    )
                for x, y, r, _ in pts:
                    ax.annotate(str(r), (x, y), textcoords="offset points", xytext=(3, 3), fontsize=7, color=c)
            if exact:
                what = "static correction" if label_suffix else "modes only"
                if exact == sum(len(m["points"]) for m in meshes):
                    notes.append(f"{what}: exact at every point (≤ {EXACT:.0e}, by construction); not plotted")
                else:
                    notes.append(f"{what}: {exact} exact point(s) (≤ {EXACT:.0e}) not plotted")
            front = pareto(allpts)
            if front:
                ax.plot([p[0] for p in front], [p[1] for p in front], "k--" if filled else "k:", lw=1,
                        label="Pareto front" + label_suffix)
        if notes:
            ax.text(0.02, 0.02, "\n".join(notes), transform=ax.transAxes, fontsize=8, va="bottom",
                    bbox=dict(boxstyle="round", fc="lightyellow", alpha=0.9))
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
