#!/usr/bin/python3
"""Plots a kdrt-bench --accuracy CSV: speed against errors for each intersector, and the errors
by kind, summed over the scenes of each ray set.

usage: bench/plot_accuracy.py ACCURACY.csv [-o PREFIX] [--markdown]

Writes PREFIX.png and PREFIX.svg (PREFIX defaults to the CSV's path without .csv). With
--markdown, also prints the summary table (one row per set and intersector) as Markdown on
standard output. Errors of a row: Leaks + SelfHits + Mismatches (Mismatches already holds the
FalseHits). The oracle rows (the double-precision brute-force reference) have a speed and no
errors; they are drawn at zero errors with an open marker. Needs Debian's python3-matplotlib.
"""
import argparse
import csv
import sys

COUNTS = ("Leaks", "FalseHits", "SelfHits", "Mismatches", "SpawnedRays", "ReferenceRays", "NaiveSelfHits")


def read_rows(path):
    with open(path, newline="") as f:
        reader = csv.DictReader(f, delimiter=";")
        missing = {"Set", "Intersector", "Rays", "TraceMs"} - set(reader.fieldnames or [])
        if missing:
            sys.exit(f"plot_accuracy: {path}: not a kdrt-bench --accuracy CSV (no {', '.join(sorted(missing))} column)")
        return list(reader)


def summarise(rows):
    """Rows summed per (Set, Intersector), in first-seen order; MRays/s over all their rays."""
    sums = {}
    for r in rows:
        key = (r["Set"], r["Intersector"])
        s = sums.setdefault(key, {"Set": key[0], "Intersector": key[1], "Scenes": 0, "Rays": 0, "TraceMs": 0.0,
                                  "measured": r["Intersector"] != "oracle", "leaks_counted": False,
                                  **{c: 0 for c in COUNTS}})
        s["Scenes"] += 1
        s["Rays"] += int(r["Rays"])
        s["TraceMs"] += float(r["TraceMs"])
        s["leaks_counted"] |= bool(r.get("Leaks"))
        for c in COUNTS:
            s[c] += int(r.get(c) or 0)
    for s in sums.values():
        s["MRaysPerSec"] = s["Rays"] / (s["TraceMs"] * 1000.0) if s["TraceMs"] > 0 else 0.0
        s["Errors"] = s["Leaks"] + s["SelfHits"] + s["Mismatches"]
    return list(sums.values())


def markdown(summary):
    lines = ["| Set | Intersector | Scenes | Rays | MRays/s | Leaks | FalseHits | SelfHits / spawned | "
             "Mismatches / reference rays | NaiveSelfHits |",
             "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for s in summary:
        if not s["measured"]:
            lines.append(f"| {s['Set']} | oracle (double, brute force: the reference) | {s['Scenes']} | {s['Rays']} | "
                         f"{s['MRaysPerSec']:.3f} | | | | | |")
            continue
        leaks = str(s["Leaks"]) if s["leaks_counted"] else "-"
        lines.append(f"| {s['Set']} | {s['Intersector']} | {s['Scenes']} | {s['Rays']} | {s['MRaysPerSec']:.3f} | "
                     f"{leaks} | {s['FalseHits']} | {s['SelfHits']} / {s['SpawnedRays']} | "
                     f"{s['Mismatches']} / {s['ReferenceRays']} | {s['NaiveSelfHits']} |")
    return "\n".join(lines)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("csv", help="CSV written by kdrt-bench --accuracy")
    parser.add_argument("-o", "--output", help="prefix of the image files (default: the CSV's name)")
    parser.add_argument("--markdown", action="store_true", help="print the summary table as Markdown")
    args = parser.parse_args()
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        sys.exit("plot_accuracy: needs matplotlib: apt-get install python3-matplotlib")

    try:
        rows = read_rows(args.csv)
    except OSError as e:
        sys.exit(f"plot_accuracy: {e}")
    if not rows:
        sys.exit(f"plot_accuracy: {args.csv}: no rows")
    summary = summarise(rows)
    prefix = args.output or (args.csv[:-4] if args.csv.endswith(".csv") else args.csv)
    sets = list(dict.fromkeys(s["Set"] for s in summary))
    modes = list(dict.fromkeys(s["Intersector"] for s in summary))
    colours = {"fast": "tab:red", "watertight": "tab:blue", "oracle": "tab:gray"}
    markers = ["o", "s", "^", "D", "v", "P", "X"]

    fig, (left, right) = plt.subplots(1, 2, figsize=(13, 5.2), gridspec_kw={"width_ratios": [1.1, 1]})

    # Left: one point per set and intersector, MRays/s (one thread) against its errors.
    for i, name in enumerate(sets):
        for s in (s for s in summary if s["Set"] == name):
            mode = s["Intersector"]
            face = "none" if mode == "oracle" else colours.get(mode, "k")
            left.scatter(s["Errors"], s["MRaysPerSec"], marker=markers[i % len(markers)], s=60,
                         facecolors=face, edgecolors=colours.get(mode, "k"), linewidths=1.5)
    for mode in modes:
        label = "oracle (double-precision brute force, the reference)" if mode == "oracle" else mode
        left.scatter([], [], marker="o", facecolors="none" if mode == "oracle" else colours.get(mode, "k"),
                     edgecolors=colours.get(mode, "k"), label=label)
    for i, name in enumerate(sets):
        left.scatter([], [], marker=markers[i % len(markers)], facecolors="none", edgecolors="k", label=f"set: {name}")
    left.set_xscale("symlog", linthresh=1)
    left.set_yscale("log")
    left.set_xlim(left=-0.5)
    left.set_xlabel("errors (leaks + self-hits + mismatches), summed over the set's scenes")
    left.set_ylabel("MRays/s, one thread (all rays of the set / their trace time)")
    left.set_title("speed against errors, per ray set and intersector")
    left.grid(True, which="both", alpha=0.3)
    left.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=3)

    # Right: errors by kind, all sets together, one group of bars per intersector; hatched, the
    # self-hits the same secondary rays make when started on the surface with no offset.
    kinds = [("Leaks", "leaks", {}), ("FalseHits", "false hits", {}), ("OtherMismatches", "other mismatches", {}),
             ("SelfHits", "self-hits (kdrt_spawn_ray)", {}),
             ("NaiveSelfHits", "self-hits if spawned with no offset", {"hatch": "//", "fill": False})]
    for s in summary:
        s["OtherMismatches"] = s["Mismatches"] - s["FalseHits"]
    measured = [m for m in modes if m != "oracle"]
    width = 0.8 / len(kinds)
    for k, (column, label, style) in enumerate(kinds):
        values = [sum(s[column] for s in summary if s["Intersector"] == m) for m in measured]
        xs = [j + (k - (len(kinds) - 1) / 2) * width for j in range(len(measured))]
        bars = right.bar(xs, values, width, label=label, color=f"C{k}", edgecolor=f"C{k}", **style)
        right.bar_label(bars, labels=[str(v) for v in values], fontsize=8)
    right.set_xticks(range(len(measured)), measured)
    right.set_yscale("symlog", linthresh=1)
    tallest = max([1] + [s[c] for s in summary for c, _, _ in kinds])
    right.set_ylim(0, tallest * 30)  # room for the labels on the tallest bars
    right.set_ylabel("count, all sets")
    right.set_title("errors by kind, per intersector")
    right.grid(True, axis="y", alpha=0.3)
    right.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.08), ncol=3)

    fig.suptitle("kdrt-bench --accuracy")
    fig.tight_layout()
    for ext in ("png", "svg"):
        fig.savefig(f"{prefix}.{ext}", dpi=120, bbox_inches="tight")
    print(f"wrote {prefix}.png and .svg", file=sys.stderr if args.markdown else sys.stdout)
    if args.markdown:
        print(markdown(summary))


if __name__ == "__main__":
    main()
