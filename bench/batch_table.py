#!/usr/bin/python3
"""Prints bench/README.md's table of the batch calls: kdrt's batch against its single calls, and
Embree's single, batch and packet calls on the same rays, from kdrt-bench --batch CSVs.

usage: bench/batch_table.py LABEL=CSV [LABEL=CSV ...]

Each argument names a ray set and the CSV of its run (kdrt-bench --batch
single,batch,packet8,packet16, with --rays and --shuffle as the label says), e.g.
primary=p.csv "diffuse, shuffled=ds.csv"; a CSV may hold several meshes, one SAH tree and one
Embree build quality each, and its rows are read as bench/plot_bench.py reads them (the plain
queries; the start cells' rows where there are any).
A row of the table per mesh and ray set, in the order given, and per kernel of kdrt-bench
--kernel (the Kernel column; a CSV without it is one kernel): when the CSVs hold more than one
kernel, a Kernel column after Rays names each row's, Embree's figures repeated on each. Each
figure is the median MRays/s of the repetitions (kdrt-bench --repeat) of one tree or build;
columns:

  kdrt single, batch   kdrt_intersect (kdrt_occluded) a ray at a time; kdrt_intersect_batch
                       (kdrt_occluded_batch) on --batch-size rays at a time
  batch / single       the two over each other: above 1, the batch is faster
  Embree 1 / 1M / 8 / 16   rtcIntersect1, rtcIntersect1M (COHERENT), rtcIntersect8, rtcIntersect16
                       (or the rtcOccluded forms), MEDIUM build
  batch / Embree best  kdrt's batch over the fastest of Embree's four
  Mismatches           summed over every row used
"""
import argparse
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from plot_bench import median_by, read_rows  # noqa: E402  (the same reading and repetition rule)

TOOL = "batch_table"
EMBREE_CALLS = ("single", "batch", "packet8", "packet16")


def parse_sets(arguments):
    """[(label, path)] from LABEL=CSV arguments (the last '=' splits, so a label may hold one)."""
    sets = []
    for argument in arguments:
        label, sep, path = argument.rpartition("=")
        if not sep or not label or not path:
            sys.exit(f"{TOOL}: want LABEL=CSV, got '{argument}'")
        sets.append((label, path))
    return sets


def kernel(row):
    """The row's kernel (kdrt-bench --kernel's Kernel column): empty on Embree rows and in CSVs
    older than the column."""
    return row.get("Kernel") or ""


def one_build_each(path, rows):
    """Exits unless each mesh has one kind of SAH tree per kernel and one Embree quality in the
    CSV: the medians are over repetitions, never over different builds."""
    kinds = {}
    for r in rows:
        tree = (r["Builder"], r["MaxLeafSize"], r.get("SahCosts"), r.get("Quality"), r.get("Intersector"))
        kinds.setdefault((r["Mesh"], r["Builder"], kernel(r)), set()).add(tree)
    for (mesh, builder, _), trees in kinds.items():
        if len(trees) > 1:
            sys.exit(f"{TOOL}: {path}: {mesh} has {len(trees)} kinds of {builder} build (leaf size, costs, quality or "
                     f"intersector): give a CSV of one each")


def first_seen(values):
    seen = []
    for v in values:
        if v not in seen:
            seen.append(v)
    return seen


def summarise(label, rows):
    """The table's rows for one ray set: a dict per mesh and kdrt kernel, in first-seen order."""
    speed = median_by(rows, lambda r: (r["Mesh"], r["Builder"], r.get("Call") or "single", kernel(r)),
                      lambda r: float(r["MRaysPerSec"]))
    summary = []
    for mesh in first_seen(r["Mesh"] for r in rows):
        of_mesh = [r for r in rows if r["Mesh"] == mesh]
        embree = {call: speed.get((mesh, "embree", call, "")) for call in EMBREE_CALLS}
        embree_mismatches = sum(int(r["Mismatches"] or 0) for r in of_mesh if r["Builder"] == "embree")
        triangles = int(of_mesh[0]["Triangles"])
        for k in first_seen(kernel(r) for r in of_mesh if r["Builder"] == "sah") or [""]:
            kd = {call: speed.get((mesh, "sah", call, k)) for call in ("single", "batch")}
            mismatches = embree_mismatches + sum(int(r["Mismatches"] or 0) for r in of_mesh
                                                 if r["Builder"] == "sah" and kernel(r) == k)
            summary.append({"mesh": mesh, "label": label, "kernel": k, "triangles": triangles, "kdrt": kd,
                            "embree": embree, "mismatches": mismatches})
    return summary


def figure(value):
    return "-" if value is None else f"{value:.2f}"


def ratio(a, b):
    return "-" if a is None or not b else f"{a / b:.2f}x"


def markdown(summary):
    """The table; a Kernel column after Rays when the rows hold more than one kernel."""
    kernels = len({s["kernel"] for s in summary}) > 1
    lines = ["| Mesh | Triangles | Rays | " + ("Kernel | " if kernels else "") + "kdrt single | kdrt batch | "
             "batch / single | Embree 1 | Embree 1M | Embree 8 | Embree 16 | batch / Embree best | Mismatches |",
             "|---|---:|---|" + ("---|" if kernels else "") + "---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for s in summary:
        kd, embree = s["kdrt"], s["embree"]
        known = [v for v in embree.values() if v is not None]
        best = max(known) if known else None
        lines.append("| " + " | ".join([
            s["mesh"], f"{s['triangles']:,}", s["label"], *([s["kernel"] or "-"] if kernels else []),
            figure(kd["single"]), figure(kd["batch"]), ratio(kd["batch"], kd["single"]),
            *(figure(embree[c]) for c in EMBREE_CALLS), ratio(kd["batch"], best), str(s["mismatches"])]) + " |")
    return "\n".join(lines)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter,
                                     epilog=__doc__.split("\n\n", 2)[2])
    parser.add_argument("sets", nargs="+", metavar="LABEL=CSV", help="a ray set's label and its kdrt-bench CSV")
    args = parser.parse_args()
    summary = []
    for label, path in parse_sets(args.sets):
        try:
            rows = [r for r in read_rows(path, TOOL, every_call=True) if r["Builder"] in ("sah", "embree")]
        except OSError as e:
            sys.exit(f"{TOOL}: {e}")
        if not rows:
            sys.exit(f"{TOOL}: {path} holds no SAH or Embree rows")
        one_build_each(path, rows)
        summary += summarise(label, rows)
    print(markdown(summary))


if __name__ == "__main__":
    main()
