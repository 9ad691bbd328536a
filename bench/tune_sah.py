#!/usr/bin/python3
"""Measures the SAH builder over a grid of cost constants (traversal K_T, intersection K_I,
empty bonus EB) with kdrt-bench, on primary and on diffuse rays, and prints a Markdown table: per
setting, the geometric mean over the meshes of MRays/s (primary, diffuse), build ms and bytes per
triangle, each also relative to the best setting.

usage: bench/tune_sah.py [options] MESH_OR_FOLDER ...
       bench/tune_sah.py --from PRIMARY.csv DIFFUSE.csv

It runs kdrt-bench twice (primary rays, then --rays diffuse), each run building every mesh once
per setting (--builder sah --sah-costs GRID --leaf-sizes 4 --compare none), tracing on one thread. Repetitions
(--repeat) give several rows per mesh and setting; each figure is their median, as
bench/plot_bench.py takes it. Build ms is the median over the rows of both runs. Mismatches
(summed over both runs) must be 0 everywhere; a setting with any is marked.

The default grid holds pbrt-v3's constants (1:80:0.5), Wald & Havran's (15:20:0.2) and kdrt.h's
defaults (30:20:0.1, chosen with this tool), and the K_T/K_I ratios 1/80, 1/40, 1/20, 1/10, 1/4,
1/2, 3/4, 1, 3/2, 9/4 and 3 (K_I = 20 but for 1/80, written 1:80 as pbrt has it; only the ratio
shapes the tree), each with the empty bonuses 0.05, 0.1, 0.2, 0.5 and 0.8: 55 settings. The table is sorted by the geometric mean of the primary
and diffuse speeds, best first. The SAH cost is not compared: each setting prices its tree in
its own units.
"""
import argparse
import math
import os
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from plot_bench import median_by, read_rows  # noqa: E402  (the same reading and repetition rule)

TOOL = "tune_sah"
REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PBRT, WALD_HAVRAN, KDRT = "1:80:0.5", "15:20:0.2", "30:20:0.1"
RATIOS = [(1, 80), (0.5, 20), (1, 20), (2, 20), (5, 20), (10, 20), (15, 20), (20, 20), (30, 20), (45, 20),
          (60, 20)]
BONUSES = [0.05, 0.1, 0.2, 0.5, 0.8]
NOTES = {PBRT: "pbrt-v3", WALD_HAVRAN: "Wald & Havran", KDRT: "kdrt.h's default"}


def default_grid():
    return [f"{kt:g}:{ki:g}:{eb:g}" for kt, ki in RATIOS for eb in BONUSES]


def geomean(values):
    return math.exp(sum(math.log(v) for v in values) / len(values)) if values and all(v > 0 for v in values) else None


def run_bench(bench, meshes, kind, grid, args, out_csv):
    cmd = [bench, "--builder", "sah", "--leaf-sizes", str(args.leaf_size), "--sah-costs", ",".join(grid), "--compare", "none",
           "--size", args.size, "--repeat", str(args.repeat), "--reference-rays", str(args.reference_rays), "-o", out_csv]
    if kind == "diffuse":
        cmd += ["--rays", "diffuse"]
    cmd += meshes
    print(f"{TOOL}: {' '.join(cmd)}", file=sys.stderr, flush=True)
    result = subprocess.run(cmd)
    if result.returncode != 0:
        sys.exit(f"{TOOL}: kdrt-bench failed (exit {result.returncode}); see its messages above")


def summarise(primary_rows, diffuse_rows, leaf_size):
    """Per setting (SahCosts), in the order first seen: geometric means over the meshes measured
    for every setting, and the mismatches."""
    rows = [dict(r, kind="primary") for r in primary_rows] + [dict(r, kind="diffuse") for r in diffuse_rows]
    rows = [r for r in rows if r.get("Builder") == "sah" and int(r["MaxLeafSize"]) == leaf_size]
    if not rows:
        sys.exit(f"{TOOL}: no SAH rows of leaf size {leaf_size} in the CSVs")
    if "SahCosts" not in rows[0]:
        sys.exit(f"{TOOL}: the CSVs have no SahCosts column: they come from a kdrt-bench older than --sah-costs")
    mesh_of = lambda r: (r["Mesh"], int(r.get("Triangles") or 0))  # noqa: E731
    settings = []
    for r in rows:
        if r["SahCosts"] not in settings:
            settings.append(r["SahCosts"])
    mrays = median_by(rows, lambda r: (r["SahCosts"], r["kind"], mesh_of(r)), lambda r: float(r["MRaysPerSec"]))
    build = median_by(rows, lambda r: (r["SahCosts"], mesh_of(r)), lambda r: float(r["BuildMs"]))
    per_tri = median_by(rows, lambda r: (r["SahCosts"], mesh_of(r)),
                        lambda r: float(r["TreeBytes"]) / max(1, int(r["Triangles"])))
    # Only meshes every setting has figures for, so the means compare like with like.
    meshes = {}
    for k in ("primary", "diffuse"):
        measured = [{m for (ss, kk, m) in mrays if ss == s and kk == k} for s in settings]
        meshes[k] = set.intersection(*measured)
    both = meshes["primary"] | meshes["diffuse"]
    out = []
    for s in settings:
        mism = sum(int(r.get("Mismatches") or 0) for r in rows if r["SahCosts"] == s)
        out.append({
            "setting": s,
            "primary": geomean([mrays[(s, "primary", m)] for m in sorted(meshes["primary"])]),
            "diffuse": geomean([mrays[(s, "diffuse", m)] for m in sorted(meshes["diffuse"])]),
            "build_ms": geomean([build[(s, m)] for m in sorted(both) if (s, m) in build]),
            "bytes": geomean([per_tri[(s, m)] for m in sorted(both) if (s, m) in per_tri]),
            "mismatches": mism,
        })
    return out, meshes


def markdown(summary, meshes):
    def best(key, pick):
        vals = [s[key] for s in summary if s[key] is not None]
        return pick(vals) if vals else None

    bests = {"primary": best("primary", max), "diffuse": best("diffuse", max),
             "build_ms": best("build_ms", min), "bytes": best("bytes", min)}

    def cell(s, key, fmt):
        v, b = s[key], bests[key]
        if v is None:
            return "-"
        return f"{fmt(v)} ({v / b:.2f})" if b else fmt(v)

    def speed(s):
        return geomean([v for v in (s["primary"], s["diffuse"]) if v is not None]) or 0.0

    ordered = sorted(summary, key=speed, reverse=True)
    lines = ["| KT:KI:EB | KT/KI | Primary MRays/s (of best) | Diffuse MRays/s (of best) | Build ms (of best) | "
             "Bytes / triangle (of best) | Mismatches |",
             "|---|---:|---:|---:|---:|---:|---:|"]
    for s in ordered:
        kt, ki, _ = (float(x) for x in s["setting"].split(":"))
        name = s["setting"] + (f" ({NOTES[s['setting']]})" if s["setting"] in NOTES else "")
        lines.append("| " + " | ".join([
            name, f"{kt / ki:.4g}",
            cell(s, "primary", lambda v: f"{v:.2f}"), cell(s, "diffuse", lambda v: f"{v:.2f}"),
            cell(s, "build_ms", lambda v: f"{v:.1f}"), cell(s, "bytes", lambda v: f"{v:.1f}"),
            str(s["mismatches"]) + ("" if s["mismatches"] == 0 else " (!)"),
        ]) + " |")
    names = lambda k: ", ".join(f"{m} ({t})" for m, t in sorted(meshes[k], key=lambda mt: mt[1])) or "none"  # noqa: E731
    lines.append("")
    lines.append(f"Geometric means over the meshes: primary {names('primary')}; diffuse {names('diffuse')}. "
                 "In parentheses: the figure over the best setting's (speed: higher is better; build time and "
                 "memory: lower is better).")
    return "\n".join(lines)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter,
                                     epilog=__doc__.split("\n\n", 2)[2])
    parser.add_argument("inputs", nargs="*", metavar="MESH_OR_FOLDER", help="meshes for kdrt-bench")
    parser.add_argument("--bench", default=os.path.join(REPO, "build", "bench", "kdrt-bench"),
                        help="the kdrt-bench to run (default: build/bench/kdrt-bench of this repository)")
    parser.add_argument("--grid", metavar="LIST",
                        help="comma-separated KT:KI:EB settings instead of the default grid (pbrt-v3's and Wald "
                             "& Havran's are always added)")
    parser.add_argument("--size", default="800x800", help="frame size WxH (default 800x800)")
    parser.add_argument("--repeat", type=int, default=1, help="rows per mesh and setting (default 1)")
    parser.add_argument("--leaf-size", type=int, default=4, help="max leaf size (default 4)")
    parser.add_argument("--reference-rays", type=int, default=20000,
                        help="rays per frame checked against the reference (default 20000)")
    parser.add_argument("--csv", metavar="PREFIX",
                        help="keep kdrt-bench's CSVs as PREFIX-primary.csv and PREFIX-diffuse.csv "
                             "(default: a temporary folder, removed)")
    parser.add_argument("--from", dest="from_csv", nargs=2, metavar=("PRIMARY.csv", "DIFFUSE.csv"),
                        help="make the table from CSVs of an earlier run instead of running kdrt-bench")
    parser.add_argument("-o", "--output", help="also write the table to this file")
    args = parser.parse_args()

    if args.from_csv:
        if args.inputs:
            parser.error("--from takes the CSVs; give no meshes with it")
        primary_csv, diffuse_csv = args.from_csv
        tmp = None
    else:
        if not args.inputs:
            parser.error("give the meshes (files or folders) to measure, or --from PRIMARY.csv DIFFUSE.csv")
        if not os.access(args.bench, os.X_OK):
            sys.exit(f"{TOOL}: no kdrt-bench at {args.bench}: build it (see README) or give --bench PATH")
        grid = args.grid.split(",") if args.grid else default_grid()
        for named in (PBRT, WALD_HAVRAN, KDRT):
            if named not in grid:
                grid.insert(0, named)
        tmp = None if args.csv else tempfile.TemporaryDirectory(prefix="tune_sah-")
        prefix = args.csv or os.path.join(tmp.name, "tune")
        primary_csv, diffuse_csv = f"{prefix}-primary.csv", f"{prefix}-diffuse.csv"
        run_bench(args.bench, args.inputs, "primary", grid, args, primary_csv)
        run_bench(args.bench, args.inputs, "diffuse", grid, args, diffuse_csv)
    try:
        primary, diffuse = read_rows(primary_csv, TOOL), read_rows(diffuse_csv, TOOL)
    except OSError as e:
        sys.exit(f"{TOOL}: {e}")
    if tmp:
        tmp.cleanup()
    summary, meshes = summarise(primary, diffuse, args.leaf_size)
    table = markdown(summary, meshes)
    print(table)
    if args.output:
        with open(args.output, "w") as f:
            f.write(table + "\n")
        print(f"{TOOL}: wrote {args.output}", file=sys.stderr)


if __name__ == "__main__":
    main()
