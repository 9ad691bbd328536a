#!/usr/bin/python3
"""Draws the construction of a kd-tree step by step, like the original report's hand-drawn
Figures 2-5, from the JSON that kdrt-construction writes (the tree kdrt really built).

Step 0 shows the triangles and the root box; each following step one inner node, breadth first:
its box (thick), the split plane (red), the median centroid it passes through (median builder),
the node's triangles coloured by the side they went to (below / left, above / right, or both,
taken from which children's subtrees refer to them) and the children's boxes (dashed). Earlier
splits stay drawn in grey. One SVG and one PNG per step, named BUILDER_stepNN, and with two or
more inputs a side-by-side figure of their final partitions (a_vs_b.svg/.png).

Example (from a build directory):
  tools/kdrt-construction --builder median -o median.json
  tools/kdrt-construction --builder sah -o sah.json
  ../tools/construction_pictures.py median.json sah.json -o ../tools/images/construction
"""
import argparse
import json
import os
import sys

try:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Polygon, Rectangle
except ImportError:
    sys.exit("construction_pictures.py: needs matplotlib (Debian: apt-get install python3-matplotlib)")

SIDE_COLOURS = {"below": "#3b7dd8", "above": "#f08c2a", "both": "#9b4fc4"}
# No creation date in the files, so drawing again changes nothing that did not change.
METADATA = {"svg": {"Date": None}, "png": {}}
SIDE_LABELS = {"below": "below / left only", "above": "above / right only", "both": "both sides"}


def load(path):
    try:
        with open(path) as f:
            data = json.load(f)
    except (OSError, ValueError) as e:
        sys.exit(f"construction_pictures.py: cannot read {path}: {e}")
    for key in ("builder", "triangles", "root_box", "steps", "leaves"):
        if key not in data:
            sys.exit(f"construction_pictures.py: {path} is not kdrt-construction output (no '{key}')")
    return data


def centroid(tri):
    return (sum(p[0] for p in tri) / 3.0, sum(p[1] for p in tri) / 3.0)


def draw_box(ax, box, **style):
    (x0, y0), (x1, y1) = box
    ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, **style))


def split_segment(step):
    (x0, y0), (x1, y1) = step["box"]
    s = step["split"]
    return ([s, s], [y0, y1]) if step["axis"] == "x" else ([x0, x1], [s, s])


def frame(ax, data, title):
    (x0, y0), (x1, y1) = data["root_box"]
    pad = 0.04 * max(x1 - x0, y1 - y0)
    ax.set_xlim(x0 - pad, x1 + pad)
    ax.set_ylim(y0 - pad, y1 + pad)
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])
    ax.set_title(title, fontsize=9)


def draw_triangles(ax, data, colours, labels=True):
    for i, tri in enumerate(data["triangles"]):
        face = colours.get(i)
        ax.add_patch(Polygon([p[:2] for p in tri], closed=True, facecolor=face or "none",
                             edgecolor="#555555" if face else "#bbbbbb", alpha=0.75 if face else 1.0,
                             linewidth=0.8))
        if labels:
            cx, cy = centroid(tri)
            ax.text(cx, cy, str(i), fontsize=6, ha="center", va="center", color="#222222" if face else "#999999")


def draw_step(data, k, out_dir, formats):
    """k = 0: the triangles and the root box; k >= 1: steps[k - 1]."""
    fig, ax = plt.subplots(figsize=(4.2, 4.2))
    builder = data["builder"]
    draw_box(ax, data["root_box"], edgecolor="black", linewidth=0.8)
    if k == 0:
        draw_triangles(ax, data, {i: "#9fb8d8" for i in range(len(data["triangles"]))})
        title = f"{builder}, step 0: {len(data['triangles'])} triangles, the root box"
    else:
        step = data["steps"][k - 1]
        for earlier in data["steps"][:k - 1]:
            xs, ys = split_segment(earlier)
            ax.plot(xs, ys, color="#999999", linewidth=0.8)
        draw_triangles(ax, data, {t: SIDE_COLOURS[s] for t, s in zip(step["triangles"], step["sides"])})
        draw_box(ax, step["below_box"], edgecolor=SIDE_COLOURS["below"], linewidth=1.2, linestyle="--")
        draw_box(ax, step["above_box"], edgecolor=SIDE_COLOURS["above"], linewidth=1.2, linestyle="--")
        draw_box(ax, step["box"], edgecolor="black", linewidth=1.8)
        xs, ys = split_segment(step)
        ax.plot(xs, ys, color="#d62728", linewidth=1.8)
        if "median_centroid" in step:
            mx, my = step["median_centroid"]
            ax.plot([mx], [my], marker="o", markersize=5, color="black")
        title = (f"{builder}, step {k}: node {step['node']} (depth {step['depth']}), "
                 f"{step['axis']} = {step['split']:.3g}")
        handles = [Polygon([[0, 0]], facecolor=SIDE_COLOURS[s], edgecolor="#555555", alpha=0.75,
                           label=SIDE_LABELS[s]) for s in ("below", "above", "both")]
        if "median_centroid" in step:
            handles.append(plt.Line2D([], [], marker="o", color="black", linestyle="none", markersize=5,
                                      label="median centroid"))
        ax.legend(handles=handles, fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.01), ncol=2,
                  frameon=False)
    frame(ax, data, title)
    fig.tight_layout()
    name = os.path.join(out_dir, f"{builder}_step{k:02d}")
    for fmt in formats:
        fig.savefig(f"{name}.{fmt}", dpi=90, bbox_inches="tight", metadata=METADATA[fmt])
    plt.close(fig)


def draw_final(datas, out_dir, formats):
    fig, axes = plt.subplots(1, len(datas), figsize=(4.0 * len(datas), 4.2))
    for ax, data in zip(axes, datas):
        draw_box(ax, data["root_box"], edgecolor="black", linewidth=1.0)
        draw_triangles(ax, data, {i: "#9fb8d8" for i in range(len(data["triangles"]))})
        for step in data["steps"]:
            xs, ys = split_segment(step)
            ax.plot(xs, ys, color="#d62728", linewidth=1.2)
        refs = sum(len(leaf["triangles"]) for leaf in data["leaves"])
        frame(ax, data, f"{data['builder']}: {len(data['steps'])} splits, {len(data['leaves'])} leaves, "
                        f"{refs} references")
    fig.tight_layout()
    name = os.path.join(out_dir, "_vs_".join(d["builder"] for d in datas))
    for fmt in formats:
        fig.savefig(f"{name}.{fmt}", dpi=90, bbox_inches="tight", metadata=METADATA[fmt])
    plt.close(fig)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("json", nargs="+", help="kdrt-construction output, one file per builder")
    parser.add_argument("-o", "--output-dir", required=True, help="folder for the pictures (created if missing)")
    parser.add_argument("--formats", default="svg,png", help="comma-separated, default svg,png")
    args = parser.parse_args()
    formats = [f for f in args.formats.split(",") if f]
    bad = [f for f in formats if f not in ("svg", "png")]
    if bad or not formats:
        sys.exit(f"construction_pictures.py: --formats takes svg and png, not {','.join(bad) or 'nothing'}")
    datas = [load(p) for p in args.json]
    builders = [d["builder"] for d in datas]
    if len(set(builders)) != len(builders):
        sys.exit("construction_pictures.py: one input per builder (their pictures share names)")
    try:
        os.makedirs(args.output_dir, exist_ok=True)
    except OSError as e:
        sys.exit(f"construction_pictures.py: cannot create {args.output_dir}: {e}")
    plt.rcParams["svg.fonttype"] = "none"  # text as text: smaller files
    plt.rcParams["svg.hashsalt"] = "kdrt"  # the same SVG on every run
    for data in datas:
        for k in range(len(data["steps"]) + 1):
            draw_step(data, k, args.output_dir, formats)
        print(f"{data['builder']}: steps 0-{len(data['steps'])} -> {args.output_dir}")
    if len(datas) > 1:
        draw_final(datas, args.output_dir, formats)
        print(f"{'_vs_'.join(builders)} -> {args.output_dir}")


if __name__ == "__main__":
    main()
