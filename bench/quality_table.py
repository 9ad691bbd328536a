#!/usr/bin/python3
"""Prints bench/README.md's table of the SAH builder's quality levels (kdrt_build_options.quality)
beside Embree, from the CSVs kdrt-bench writes with --builder sah --quality fast,medium,high
--compare embree.

usage: bench/quality_table.py --primary CSV [CSV ...] --diffuse CSV [CSV ...]
                              --two-threads CSV [CSV ...]

--primary and --diffuse take the one-thread runs of each ray kind (their build times are pooled),
--two-threads the runs with --build-threads 2. Each figure is the median of a mesh's repetitions
(as bench/plot_bench.py takes them). Columns:

  Build ms, 1 / 2 threads  the level's build, and over it Embree's at the same thread count: LOW
                           quality beside FAST (and MEDIUM too), MEDIUM beside MEDIUM and HIGH
  2 threads                one thread's build time over two threads'
  Primary, Diffuse         MRays/s, tracing on one thread, and the level's speed over HIGH's
  SAH cost, Bytes / tri    the level's tree
  Mismatches               summed over the level's rows (every CSV)
"""
import argparse
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from plot_bench import median_by, read_rows  # noqa: E402  (the same reading and repetition rule)

TOOL = "quality_table"
LEVELS = ("fast", "medium", "high")


def load(paths, tag):
    rows = []
    for path in paths:
        try:
            for r in read_rows(path, TOOL):
                if "Quality" not in r:
                    sys.exit(f"{TOOL}: {path} has no Quality column: it comes from a kdrt-bench older than --quality")
                r["tag"] = tag
                rows.append(r)
        except OSError as e:
            sys.exit(f"{TOOL}: {e}")
    return rows


def fmt(x, digits=1):
    if x is None:
        return "-"
    return f"{x:.{digits}f}" if x < 100 else f"{x:.0f}"


def ratio(a, b):
    return a / b if a is not None and b else None


def build_cell(ms, embree, level):
    """'27.3 (7.8x LOW, 1.4x MEDIUM)': the level's time and its ratios to Embree's."""
    if ms is None:
        return "-"
    peers = ("low", "medium") if level == "fast" else ("medium",)
    parts = [f"{ratio(ms, embree.get(p)):.1f}x {p.upper()}" for p in peers if embree.get(p)]
    return f"{fmt(ms)} ({', '.join(parts)})" if parts else fmt(ms)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--primary", nargs="+", required=True)
    parser.add_argument("--diffuse", nargs="+", required=True)
    parser.add_argument("--two-threads", nargs="+", required=True)
    args = parser.parse_args()
    rows = load(args.primary, "primary") + load(args.diffuse, "diffuse") + load(args.two_threads, "two")

    mesh_of = lambda r: (r["Mesh"], int(r.get("Triangles") or 0))  # noqa: E731
    level_of = lambda r: r["Builder"] + ":" + r["Quality"]  # noqa: E731  sah:fast, embree:low, ...
    meshes = []
    for r in rows:
        if mesh_of(r) not in meshes:
            meshes.append(mesh_of(r))

    def med(col, tags, key):
        return median_by([r for r in rows if r["tag"] in tags and r.get(col)], key, lambda r: float(r[col]))

    build1 = med("BuildMs", ("primary", "diffuse"), lambda r: (mesh_of(r), level_of(r)))
    build2 = med("BuildMs", ("two",), lambda r: (mesh_of(r), level_of(r)))
    mrays = med("MRaysPerSec", ("primary", "diffuse"), lambda r: (mesh_of(r), r["tag"], level_of(r)))
    sah_cost = med("SahCost", ("primary", "diffuse"), lambda r: (mesh_of(r), level_of(r)))
    tree_bytes = med("TreeBytes", ("primary", "diffuse"), lambda r: (mesh_of(r), level_of(r)))

    print("| Mesh | Triangles | Quality | Build ms, 1 thread | Build ms, 2 threads | 2 threads | "
          "Primary MRays/s (of HIGH) | Diffuse MRays/s (of HIGH) | SAH cost | Bytes / triangle | Mismatches |")
    print("|---|---:|---|---|---|---:|---|---|---:|---:|---:|")
    for m in meshes:
        embree1 = {p: build1.get((m, "embree:" + p)) for p in ("low", "medium")}
        embree2 = {p: build2.get((m, "embree:" + p)) for p in ("low", "medium")}
        for level in LEVELS:
            key = (m, "sah:" + level)
            if key not in build1:
                continue
            b1, b2 = build1.get(key), build2.get(key)
            speed = {k: mrays.get((m, k, "sah:" + level)) for k in ("primary", "diffuse")}
            high = {k: mrays.get((m, k, "sah:high")) for k in ("primary", "diffuse")}
            trace = [f"{fmt(speed[k], 2)} ({ratio(speed[k], high[k]):.2f}x)" if ratio(speed[k], high[k])
                     else fmt(speed[k], 2) for k in ("primary", "diffuse")]
            up = ratio(b1, b2)
            mism = sum(int(r.get("Mismatches") or 0) for r in rows if mesh_of(r) == m and level_of(r) == "sah:" + level)
            per_tri = ratio(tree_bytes.get(key), m[1])
            print(f"| {m[0]} | {m[1]} | {level.upper()} | {build_cell(b1, embree1, level)} | "
                  f"{build_cell(b2, embree2, level)} | {f'{up:.2f}x' if up else '-'} | {trace[0]} | {trace[1]} | "
                  f"{fmt(sah_cost.get(key))} | {fmt(per_tri, 0)} | {mism} |")
    print()
    print("(Embree: rtcIntersect1, its build on a device of the same thread count; each figure the median"
          " of the repetitions.)")


if __name__ == "__main__":
    main()
