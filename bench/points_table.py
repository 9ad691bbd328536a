#!/usr/bin/env python3
"""The tables of bench/README.md's "Closest point and overlap" from kdrt-bench --points CSVs.

    points_table.py bench/results/points.csv bench/results/points-bunny-1m.csv

Prints two Markdown tables: closest point (kdrt against Embree's rtcPointQuery, wall and CPU
time, disagreements with the brute force) and overlap (kdrt's box and sphere queries by size).
"""
import csv
import sys


def rows(paths):
    for path in paths:
        with open(path, newline="") as f:
            yield from csv.DictReader(f, delimiter=";")


def main(paths):
    if not paths:
        sys.exit(__doc__)
    all_rows = list(rows(paths))
    print("| Mesh | Triangles | Points | Queries | kdrt us/query | Embree us/query | Embree / kdrt (wall) | Embree / kdrt (CPU time) | Disagreements kdrt / Embree (of) | Largest error kdrt / Embree |")
    print("|---|---:|---|---:|---:|---:|---:|---:|---|---|")
    for r in all_rows:
        if r["Query"] != "closest":
            continue
        n = int(r["Queries"])
        kdrt_us = 1000.0 * float(r["KdrtMs"]) / n
        embree_us = 1000.0 * float(r["EmbreeMs"]) / n
        print(f"| {r['Mesh']} | {r['Triangles']} | {r['Kind']} | {n} | {kdrt_us:.2f} | {embree_us:.2f} | "
              f"{float(r['Ratio']):.2f}x | {float(r['CpuRatio']):.2f}x | "
              f"{r['KdrtMismatches']} / {r['EmbreeMismatches']} ({r['ReferenceQueries']}) | "
              f"{float(r['KdrtMaxError']):.1e} / {float(r['EmbreeMaxError']):.1e} |")
    print()
    print("| Mesh | Query | Size | Queries | Triangles found / query | us/query | ns/triangle found | Disagreements (of) |")
    print("|---|---|---:|---:|---:|---:|---:|---|")
    for r in all_rows:
        if r["Query"] == "closest":
            continue
        n = int(r["Queries"])
        found = int(r["Found"])
        us = 1000.0 * float(r["KdrtMs"]) / n
        per = 1e6 * float(r["KdrtMs"]) / found if found else 0.0
        check = f"{r['KdrtMismatches']} ({r['ReferenceQueries']})" if int(r["ReferenceQueries"]) else "-"
        print(f"| {r['Mesh']} | {r['Query']} | {float(r['Size']) * 100:g}% | {n} | {found / n:.1f} | {us:.1f} | {per:.0f} | {check} |")


if __name__ == "__main__":
    main(sys.argv[1:])
