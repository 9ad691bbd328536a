#!/usr/bin/python3
"""Plots a kdrt-bench CSV: time against max leaf size (log-log, like the original report's
figure), speedup over leaf size 0, and speed against error (kdrt beside Embree).

usage: bench/plot_bench.py BENCH.csv [-o PREFIX]

Writes PREFIX-elapsed.{png,svg}, PREFIX-speedup.{png,svg} and PREFIX-speed-vs-error.{png,svg}
(PREFIX defaults to the CSV's path without .csv). Needs Debian's python3-matplotlib.
"""
import argparse
import csv
import statistics
import sys
from collections import defaultdict


def read_rows(path, tool="plot_bench", every_call=False):
    """The rows of a kdrt-bench CSV as dicts; exits naming `tool` when it is not one. Rows of
    --query filter are left out: the tables and plots compare the plain queries; so are the rows
    of --batch's batch and packet calls (Call other than single), unless every_call (as
    bench/batch_table.py reads them). Of a run with --start cell,root (the default for diffuse
    and shadow rays), the rows from the start cells are kept: rays spawned at hits carry their
    cells, as a renderer's do."""
    with open(path, newline="") as f:
        reader = csv.DictReader(f, delimiter=";")
        missing = {"Mesh", "MaxLeafSize", "ElapsedMs"} - set(reader.fieldnames or [])
        if missing:
            sys.exit(f"{tool}: {path}: not a kdrt-bench CSV (no {', '.join(sorted(missing))} column)")
        rows = [r for r in reader
                if r.get("Query") in (None, "", "plain") and (every_call or r.get("Call") in (None, "single"))]
    if any(r.get("Start") == "cell" for r in rows):
        rows = [r for r in rows if r.get("Start") != "root"]
    return rows


def median_by(rows, key, value):
    """value(r) over the rows of each key(r), their median: how repetitions become one figure."""
    groups = defaultdict(list)
    for r in rows:
        groups[key(r)].append(value(r))
    return {k: statistics.median(v) for k, v in groups.items()}


def finish_log_log(ax, xlabel, ylabel, title):
    """Both axes logarithmic (x in powers of two: leaf sizes), labels, grid and legend."""
    ax.set_xscale("log", base=2)
    ax.set_yscale("log")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)


def save(fig, prefix, name):
    for ext in ("png", "svg"):
        fig.savefig(f"{prefix}-{name}.{ext}", dpi=120, bbox_inches="tight")
    print(f"wrote {prefix}-{name}.png and .svg")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("csv", help="CSV written by kdrt-bench")
    parser.add_argument("-o", "--output", help="prefix of the image files (default: the CSV's name)")
    args = parser.parse_args()
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        sys.exit("plot_bench: needs matplotlib: apt-get install python3-matplotlib")

    try:
        rows = read_rows(args.csv)
    except OSError as e:
        sys.exit(f"plot_bench: {e}")
    prefix = args.output or (args.csv[:-4] if args.csv.endswith(".csv") else args.csv)
    kd = [r for r in rows if r.get("Builder", "median") != "embree"]
    peer = [r for r in rows if r.get("Builder") == "embree"]
    if not kd:
        sys.exit(f"plot_bench: {args.csv}: no kd-tree rows")
    meshes = sorted({r["Mesh"] for r in kd}, key=lambda m: int(next(r.get("Triangles", "0") for r in kd if r["Mesh"] == m) or 0))
    builders = sorted({r.get("Builder", "median") for r in kd}, key=lambda b: (b != "median", b))
    style = {b: ["-", "--", ":", "-."][i % 4] for i, b in enumerate(builders)}
    colour = {m: f"C{i % 10}" for i, m in enumerate(meshes)}
    # Leaf size 0 is "no tree" whatever the builder: one value per mesh, shared by every curve.
    elapsed = median_by(kd, lambda r: (r["Mesh"], r.get("Builder", "median") if int(r["MaxLeafSize"]) else "", int(r["MaxLeafSize"])),
                        lambda r: float(r.get("TraceMs") or r["ElapsedMs"]))

    def curve(m, b, with_zero):
        return sorted((leaf, ms) for (mesh, builder, leaf), ms in elapsed.items()
                      if mesh == m and (builder == b or (with_zero and leaf == 0)))

    def label(m, b):
        return m if len(builders) == 1 else f"{m} ({b})"

    # 1. Trace time against max leaf size (leaf size 0, no tree, drawn at x = 0.5 on the log axis).
    fig, ax = plt.subplots(figsize=(8, 5))
    for m in meshes:
        for b in builders:
            pts = curve(m, b, True)
            if len(pts) > 1 or (pts and pts[0][0]):
                ax.plot([leaf if leaf else 0.5 for leaf, _ in pts], [ms for _, ms in pts], marker="o", ms=3,
                        color=colour[m], linestyle=style[b], label=label(m, b))
    finish_log_log(ax, "max leaf size (0.5 = no tree)", "trace time of the frame, ms",
                   "kdrt-bench: frame time against max leaf size")
    save(fig, prefix, "elapsed")

    # 2. Speedup over leaf size 0 (brute force).
    fig, ax = plt.subplots(figsize=(8, 5))
    for m in meshes:
        base = elapsed.get((m, "", 0))
        if not base:
            continue
        for b in builders:
            pts = [(leaf, base / ms) for leaf, ms in curve(m, b, False) if leaf > 0 and ms > 0]
            if pts:
                ax.plot([leaf for leaf, _ in pts], [s for _, s in pts], marker="o", ms=3, color=colour[m],
                        linestyle=style[b], label=label(m, b))
    finish_log_log(ax, "max leaf size", "speedup over no tree (leaf size 0)", "kdrt-bench: speedup of the kd-tree")
    save(fig, prefix, "speedup")

    # 3. Speed against error: MRays/s against mismatches per reference ray, kdrt and Embree.
    fig, ax = plt.subplots(figsize=(8, 5))
    worst = 0.0
    groups = [(f"kdrt {b} (best leaf size per mesh)", [r for r in kd if r.get("Builder", "median") == b], "o^vD"[i % 4])
              for i, b in enumerate(builders)]
    for name, subset, marker in groups + [("Embree 3", peer, "s")]:
        xs, ys, names = [], [], []
        for m in meshes:
            mine = [r for r in subset if r["Mesh"] == m and r.get("MRaysPerSec")]
            if not mine:
                continue
            best = max(mine, key=lambda r: float(r["MRaysPerSec"]))
            ref = int(best.get("ReferenceRays") or 0)
            xs.append(int(best.get("Mismatches") or 0) / ref if ref else 0.0)
            ys.append(float(best["MRaysPerSec"]))
            names.append(m)
        if xs:
            ax.scatter(xs, ys, marker=marker, label=name)
            for x, y, mesh in zip(xs, ys, names):
                ax.annotate(mesh, (x, y), textcoords="offset points", xytext=(6, -3), fontsize=7)
            worst = max(worst, max(xs))
    # Error rates are 0 or tiny fractions: linear near 0, logarithmic above 1e-5.
    ax.set_xscale("symlog", linthresh=1e-5)
    ax.set_xlim(left=-2e-6, right=max(1e-2, 10 * worst))
    ax.set_yscale("log")
    ax.set_xlabel("mismatches per reference ray (0 = agrees with double-precision brute force)")
    ax.set_ylabel("MRays/s (one thread)")
    ax.set_title("kdrt-bench: speed against error")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    save(fig, prefix, "speed-vs-error")


if __name__ == "__main__":
    main()
