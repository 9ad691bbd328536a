#!/usr/bin/python3
"""Plots MRays/s against triangle count for kdrt's SAH and median trees and Embree, on primary
and on diffuse rays, from the CSVs bench/bench_table.py reads (kdrt-bench --builder median,sah
--compare embree, a primary and a diffuse run).

usage: bench/plot_speed.py --primary CSV [CSV ...] --diffuse CSV [CSV ...] [--shadow CSV ...] [-o PREFIX]
                           [--leaf-size N] [--sah-costs KT:KI:EB] [--min-triangles N]

Writes PREFIX.png and PREFIX.svg (PREFIX defaults to the first primary CSV's path without .csv,
plus -mrays): one panel per kind of ray, both axes logarithmic, a point per mesh of at least
--min-triangles triangles (default 4000: the small seed meshes time mostly the frame's fixed
costs). The figures are bench_table.py's: the rows of one max leaf size (default 4), the median
of repetitions. Needs Debian's python3-matplotlib.
"""
import argparse
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_table import add_input_arguments, load_summary  # noqa: E402

TOOL = "plot_speed"
CURVES = (("sah", "kdrt SAH", "o", "-"), ("median", "kdrt median", "v", "--"), ("embree", "Embree 3", "s", ":"))


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter,
                                     epilog=__doc__.split("\n\n", 2)[2])
    add_input_arguments(parser)
    parser.add_argument("-o", "--output", help="prefix of the image files")
    parser.add_argument("--min-triangles", type=int, default=4000, help="leave out smaller meshes (default 4000)")
    args = parser.parse_args()
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        sys.exit(f"{TOOL}: needs matplotlib: apt-get install python3-matplotlib")

    summary, costs = load_summary(args)
    shown = sorted((s for s in summary if s["triangles"] >= args.min_triangles), key=lambda s: s["triangles"])
    if not shown:
        sys.exit(f"{TOOL}: no mesh of {args.min_triangles} triangles or more in the CSVs")
    first = args.primary[0]
    prefix = args.output or (first[:-4] if first.endswith(".csv") else first) + "-mrays"

    kinds = [k for k in ("primary", "diffuse", "shadow") if getattr(args, k)]
    fig, axes = plt.subplots(1, len(kinds), figsize=(6 * len(kinds), 5), sharex=True, sharey=True, squeeze=False)
    axes = axes[0]
    for ax, kind in zip(axes, kinds):
        for builder, label, marker, style in CURVES:
            pts = [(s["triangles"], s["mrays"][(kind, builder)], s["mesh"]) for s in shown
                   if s["mrays"][(kind, builder)] is not None]
            if pts:
                ax.plot([p[0] for p in pts], [p[1] for p in pts], marker=marker, linestyle=style, label=label)
            if builder == "sah":
                for x, y, name in pts:
                    ax.annotate(name.lower(), (x, y), textcoords="offset points", xytext=(4, -10), fontsize=7)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlim(shown[0]["triangles"] / 1.5, shown[-1]["triangles"] * 3)  # room for the names
        ax.set_xlabel("triangles in the scene (log)")
        ax.set_title(f"{kind} rays")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    axes[0].set_ylabel("MRays/s, one thread (log)")
    detail = f"max leaf size {args.leaf_size}" + (f", SAH costs {costs}" if costs else "")
    fig.suptitle(f"kdrt-bench: speed against mesh size ({detail})")
    for ext in ("png", "svg"):
        fig.savefig(f"{prefix}.{ext}", dpi=120, bbox_inches="tight")
    print(f"wrote {prefix}.png and .svg")


if __name__ == "__main__":
    main()
