#!/usr/bin/python3
"""Prints bench/README.md's table of kdrt's SAH builder against Embree and the median builder, from
the CSVs kdrt-bench writes with --builder median,sah --compare embree.

usage: bench/bench_table.py --primary CSV [CSV ...] --diffuse CSV [CSV ...] [--shadow CSV ...]
                            [--leaf-size N] [--sah-costs KT:KI:EB]

--primary takes the CSVs of primary-ray runs (kdrt-bench without --rays), --diffuse those of
--rays diffuse runs, --shadow (optional, a column of its own) those of --rays shadow runs; a mesh
may appear in any of them. Per mesh, the SAH and median rows of one
max leaf size (default 4) and the Embree rows are compared. Repetitions (kdrt-bench --repeat)
give several rows for a mesh and builder; each figure is their median, as bench/plot_bench.py
takes it. Build times are the median over the rows of both kinds of run (the same trees are
built in each). Columns:

  Triangles            the scene's (the mesh and the benchmark's two wall triangles)
  Bytes / triangle     the SAH tree's TreeBytes over Triangles
  SAH cost             the SAH tree's SahCost, priced with its own constants (SahCosts)
  Build ms             SAH / Embree (SAH over Embree)
  Primary, Diffuse     MRays/s SAH / Embree (SAH over Embree), one thread; Shadow the same for
                       kdrt_occluded against rtcOccluded1
  SAH over median      the SAH tree's MRays/s over the median tree's, primary / diffuse
  Mismatches           summed over every row used (SAH, median and Embree, both kinds)
"""
import argparse
import os

import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from plot_bench import median_by, read_rows  # noqa: E402  (the same reading and repetition rule)

TOOL = "bench_table"


KINDS = ("primary", "diffuse", "shadow")  # kdrt-bench --rays, as the CSVs are given


def load(paths, kind):
    """Every row of the CSVs, each tagged with its kind (primary or diffuse)."""
    rows = []
    for path in paths:
        try:
            for r in read_rows(path, TOOL):
                r["kind"] = kind
                rows.append(r)
        except OSError as e:
            sys.exit(f"{TOOL}: {e}")
    return rows


def choose_sah_costs(rows, wanted):
    """The SahCosts value the SAH rows are taken from: `wanted`, or the only one in the CSVs."""
    found = []
    for r in rows:
        if r.get("Builder") == "sah" and (r.get("SahCosts") or "") not in found:
            found.append(r.get("SahCosts") or "")
    if wanted is not None:
        if wanted not in found:
            sys.exit(f"{TOOL}: no SAH rows with SahCosts {wanted} (the CSVs have: {', '.join(found) or 'none'})")
        return wanted
    if len(found) > 1:
        sys.exit(f"{TOOL}: the CSVs hold SAH rows for several cost triples ({', '.join(found)}): "
                 "choose one with --sah-costs")
    return found[0] if found else ""


def one_kernel(rows):
    """Exits when the kd-tree rows ran more than one kernel (kdrt-bench --kernel's Kernel column;
    older CSVs have none): the medians would mix them."""
    found = []
    for r in rows:
        if r.get("Builder") != "embree" and r.get("Kernel") and r["Kernel"] not in found:
            found.append(r["Kernel"])
    if len(found) > 1:
        sys.exit(f"{TOOL}: the CSVs hold kd-tree rows of several kernels ({', '.join(found)}): give CSVs of one "
                 "kernel (kdrt-bench --kernel), or bench/batch_table.py, which keeps them apart")


def summarise(rows, leaf_size, sah_costs):
    """Per mesh, in first-seen order: a dict of the table's figures (None where not measured).

    Keys: mesh, triangles, bytes_per_triangle, sah_cost, build_ms[builder],
    mrays[(kind, builder)], mismatches, rows (rows used). builder is sah, median or embree."""
    def wanted(r):
        b = r.get("Builder", "median")
        if b == "embree":
            return True
        if r.get("Intersector", "watertight") not in ("watertight", ""):
            return False
        if int(r["MaxLeafSize"]) != leaf_size:
            return False
        return b == "median" or (b == "sah" and (r.get("SahCosts") or "") == sah_costs)

    used = [r for r in rows if wanted(r)]
    # A mesh is its name and triangle count: two files may share a stem (the seed's NEFERTITI and
    # common/nefertiti.obj).
    mesh_of = lambda r: (r["Mesh"], int(r.get("Triangles") or 0))  # noqa: E731
    meshes = []
    for r in rows:
        if mesh_of(r) not in meshes:
            meshes.append(mesh_of(r))

    def med(col, key):
        return median_by([r for r in used if r.get(col)], key, lambda r: float(r[col]))

    builder = lambda r: r.get("Builder", "median")  # noqa: E731
    build = med("BuildMs", lambda r: (mesh_of(r), builder(r)))
    mrays = med("MRaysPerSec", lambda r: (mesh_of(r), r["kind"], builder(r)))
    tree_bytes = med("TreeBytes", lambda r: (mesh_of(r), builder(r)))
    sah_cost = med("SahCost", lambda r: (mesh_of(r), builder(r)))
    out = []
    for m in meshes:
        mine = [r for r in used if mesh_of(r) == m]
        triangles = m[1]
        sah_bytes = tree_bytes.get((m, "sah"))
        out.append({
            "mesh": m[0],
            "triangles": triangles,
            "bytes_per_triangle": sah_bytes / triangles if sah_bytes is not None and triangles else None,
            "sah_cost": sah_cost.get((m, "sah")),
            "build_ms": {b: build.get((m, b)) for b in ("sah", "median", "embree")},
            "mrays": {(k, b): mrays.get((m, k, b)) for k in KINDS for b in ("sah", "median", "embree")},
            "mismatches": sum(int(r.get("Mismatches") or 0) for r in mine),
            "rows": len(mine),
        })
    return out


def ratio(a, b):
    return a / b if a is not None and b else None


def fmt_ms(v):
    return "-" if v is None else f"{v:.0f}" if v >= 100 else f"{v:.1f}" if v >= 1 else f"{v:.2f}"


def fmt_pair(a, b, fmt, ratio_digits):
    """'a / b (a/b x)', '-' parts where a figure is missing."""
    if a is None and b is None:
        return "-"
    r = ratio(a, b)
    text = f"{fmt(a) if a is not None else '-'} / {fmt(b) if b is not None else '-'}"
    return text + (f" ({r:.{ratio_digits}f}x)" if r is not None else "")


def markdown(summary):
    mrays_fmt = lambda v: f"{v:.2f}"  # noqa: E731
    shadow = any(s["mrays"][("shadow", b)] is not None for s in summary for b in ("sah", "embree"))
    lines = ["| Mesh | Triangles | Bytes / triangle | SAH cost | Build ms SAH / Embree | "
             "Primary MRays/s SAH / Embree | Diffuse MRays/s SAH / Embree | " +
             ("Shadow MRays/s SAH / Embree | " if shadow else "") + "SAH over median, primary / diffuse | "
             "Mismatches |",
             "|---|---:|---:|---:|---|---|---|" + ("---|" if shadow else "") + "---|---:|"]
    for s in summary:
        over = [ratio(s["mrays"][(k, "sah")], s["mrays"][(k, "median")]) for k in ("primary", "diffuse")]
        over_text = " / ".join("-" if v is None else f"{v:.1f}x" for v in over)
        lines.append("| " + " | ".join([
            s["mesh"],
            str(s["triangles"]),
            "-" if s["bytes_per_triangle"] is None else f"{s['bytes_per_triangle']:.0f}",
            "-" if s["sah_cost"] is None else f"{s['sah_cost']:.1f}",
            fmt_pair(s["build_ms"]["sah"], s["build_ms"]["embree"], fmt_ms, 1),
            fmt_pair(s["mrays"][("primary", "sah")], s["mrays"][("primary", "embree")], mrays_fmt, 2),
            fmt_pair(s["mrays"][("diffuse", "sah")], s["mrays"][("diffuse", "embree")], mrays_fmt, 2),
        ] + ([fmt_pair(s["mrays"][("shadow", "sah")], s["mrays"][("shadow", "embree")], mrays_fmt, 2)] if shadow else []) + [
            over_text,
            str(s["mismatches"]),
        ]) + " |")
    return "\n".join(lines)


def add_input_arguments(parser):
    """The options that say which CSVs and rows to read (bench/plot_speed.py takes them too)."""
    parser.add_argument("--primary", nargs="+", required=True, metavar="CSV", help="kdrt-bench CSVs of primary rays")
    parser.add_argument("--diffuse", nargs="+", default=[], metavar="CSV", help="kdrt-bench CSVs of --rays diffuse")
    parser.add_argument("--shadow", nargs="+", default=[], metavar="CSV", help="kdrt-bench CSVs of --rays shadow")
    parser.add_argument("--leaf-size", type=int, default=4, help="max leaf size of the kd-tree rows (default 4)")
    parser.add_argument("--sah-costs", metavar="KT:KI:EB",
                        help="the SAH rows' SahCosts, when the CSVs hold several (as kdrt-bench writes it)")


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter,
                                     epilog=__doc__.split("\n\n", 2)[2])
    add_input_arguments(parser)
    return parser.parse_args(argv)


def load_summary(args):
    """The table's figures from the parsed arguments (bench/plot_speed.py reads them too)."""
    rows = load(args.primary, "primary") + load(args.diffuse, "diffuse") + load(args.shadow, "shadow")
    if not rows:
        sys.exit(f"{TOOL}: the CSVs hold no rows")
    one_kernel(rows)
    costs = choose_sah_costs(rows, args.sah_costs)
    summary = summarise(rows, args.leaf_size, costs)
    return summary, costs


def main():
    args = parse_args()
    summary, costs = load_summary(args)
    print(markdown(summary))
    if costs:
        print()
        print(f"(SAH rows: SahCosts {costs}, max leaf size {args.leaf_size}.)")


if __name__ == "__main__":
    main()
