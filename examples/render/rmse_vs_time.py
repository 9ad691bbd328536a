#!/usr/bin/python3
"""Renders presets at increasing samples per pixel and plots RMSE against render time (log-log).

usage: examples/render/rmse_vs_time.py [--presets A,B] [--spp 1,2,4,...] [--reference-spp N] [--size WxH]
                             [--threads N] [--set KEY=VALUE]... [--renderer PATH] [-o DIR]

For each preset (default PHASE_4_REFRACTION and PICTURE) it renders a reference EXR at
--reference-spp samples per pixel, kept in DIR and reused by later runs with the same preset,
size, spp and --set settings (--fresh-reference renders it again), then renders at each --spp count with
`kdrt-render --reference REF.exr`, timing each run's wall clock (process start to exit, so scene
loading and the tree build are included) and reading the `rmse=` line it prints.

Writes DIR/rmse_vs_time.csv (Preset;Spp;Seconds;RMSE) and DIR/rmse_vs_time.{png,svg}; each
preset's curve is drawn beside a time^-1/2 guide, the rate of Monte Carlo error at a fixed cost
per sample. --plot-only redraws the figure from the CSV. Needs Debian's python3-matplotlib.
"""
import argparse
import csv
import math
import os
import subprocess
import sys
import time
from pathlib import Path

TOOL = "rmse_vs_time"
REPO = Path(__file__).resolve().parent.parent
DEFAULT_RENDERER = REPO / "build" / "examples" / "render" / "kdrt-render"
# The reference and the measured renders use different seeds: with the same one, a renderer
# whose per-pixel streams start alike would draw the measured image's samples again inside the
# reference, and the RMSE would come out too small.
RENDER_SEED = 1
REFERENCE_SEED = 2
CSV_NAME = "rmse_vs_time.csv"
COLUMNS = ["Preset", "Spp", "Seconds", "RMSE"]


def fail(message):
    sys.exit(f"{TOOL}: {message}")


def positive_int_list(text):
    try:
        values = [int(v) for v in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"wants positive whole numbers separated by commas, got '{text}'")
    if not values or any(v < 1 for v in values):
        raise argparse.ArgumentTypeError(f"wants positive whole numbers separated by commas, got '{text}'")
    return sorted(set(values))


def positive_int(text):
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"wants a positive whole number, got '{text}'")
    return value


def size(text):
    parts = text.lower().split("x")
    if len(parts) != 2 or not all(p.isdigit() and int(p) > 0 for p in parts):
        raise argparse.ArgumentTypeError(f"wants WxH, like 320x240, got '{text}'")
    return text.lower()


def setting(text):
    key, sep, value = text.partition("=")
    if not sep or not key or not value:
        raise argparse.ArgumentTypeError(f"wants KEY=VALUE, got '{text}'")
    if key.upper() == "NSAMPLES":
        raise argparse.ArgumentTypeError("NSAMPLES is what this tool varies: use --spp and --reference-spp")
    return text


def run_renderer(args, preset, spp, seed, output, reference=None):
    """Runs kdrt-render once; returns (wall seconds, its stdout). Exits with its stderr on failure."""
    command = [str(args.renderer), "--preset", preset, "--set", f"NSAMPLES={spp}", "--size", args.size,
               "--seed", str(seed)]
    for s in args.set:
        command += ["--set", s]
    if args.threads:
        command += ["--threads", str(args.threads)]
    if reference:
        command += ["--reference", str(reference)]
    command += ["-o", str(output)]
    start = time.perf_counter()
    try:
        done = subprocess.run(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    except OSError as e:
        fail(f"cannot run {args.renderer}: {e.strerror}")
    seconds = time.perf_counter() - start
    if done.returncode != 0:
        tail = "\n".join(done.stderr.strip().splitlines()[-10:])
        fail(f"the renderer failed (exit {done.returncode}): {' '.join(command)}\n{tail}")
    return seconds, done.stdout


def read_rmse(stdout, command_hint):
    """The value of the renderer's `rmse=<value>` line."""
    for line in stdout.splitlines():
        if line.startswith("rmse="):
            try:
                value = float(line[len("rmse="):])
            except ValueError:
                break
            if math.isfinite(value) and value >= 0:
                return value
            break
    fail(f"{command_hint}: no 'rmse=<number >= 0>' line in the renderer's output:\n{stdout.strip()[:500]}")


def reference_for(args, preset):
    """The cached reference EXR of this preset, size and spp, rendered when absent."""
    # Named by everything that changes the image (not --threads: the image is the same for any).
    tag = "".join(c if c.isalnum() or c in "._=-" else "_" for c in "-".join(["", *sorted(args.set)]))
    path = args.output / f"reference-{preset}-{args.size}-{args.reference_spp}spp{tag}.exr"
    if path.is_file() and path.stat().st_size > 0 and not args.fresh_reference:
        print(f"{preset}: reference {path} (cached)", file=sys.stderr)
        return path
    print(f"{preset}: rendering the reference at {args.reference_spp} spp ...", file=sys.stderr)
    seconds, _ = run_renderer(args, preset, args.reference_spp, REFERENCE_SEED, path)
    if not path.is_file():
        fail(f"the renderer exited 0 but wrote no reference {path}")
    print(f"{preset}: reference {path} in {seconds:.2f} s", file=sys.stderr)
    return path


def measure(args):
    """Renders every preset at every spp; returns the CSV rows."""
    rows = []
    renders = args.output / "renders"
    renders.mkdir(exist_ok=True)
    for preset in args.presets:
        reference = reference_for(args, preset)
        for spp in args.spp:
            output = renders / f"{preset}-{args.size}-{spp}spp.exr"
            seconds, stdout = run_renderer(args, preset, spp, RENDER_SEED, output, reference)
            rmse = read_rmse(stdout, f"{preset} at {spp} spp")
            print(f"{preset}: {spp:>5} spp  {seconds:8.3f} s  rmse {rmse:.6g}", file=sys.stderr)
            rows.append({"Preset": preset, "Spp": spp, "Seconds": seconds, "RMSE": rmse})
    return rows


def write_csv(rows, path):
    tmp = path.with_name(path.name + ".partial")
    with open(tmp, "w", newline="") as f:
        writer = csv.writer(f, delimiter=";")
        writer.writerow(COLUMNS)
        for r in rows:
            writer.writerow([r["Preset"], r["Spp"], f"{r['Seconds']:.6f}", f"{r['RMSE']:.8g}"])
    os.replace(tmp, path)  # a run stopped half way leaves the previous CSV, not half of one
    print(f"wrote {path}")


def read_csv(path):
    try:
        with open(path, newline="") as f:
            reader = csv.DictReader(f, delimiter=";")
            if reader.fieldnames != COLUMNS:
                fail(f"{path}: not an {TOOL} CSV (header {';'.join(reader.fieldnames or [])}, "
                     f"expected {';'.join(COLUMNS)})")
            rows = []
            for n, r in enumerate(reader, start=2):
                try:
                    rows.append({"Preset": r["Preset"], "Spp": int(r["Spp"]), "Seconds": float(r["Seconds"]),
                                 "RMSE": float(r["RMSE"])})
                except (TypeError, ValueError):
                    fail(f"{path}:{n}: a row that is not Preset;Spp;Seconds;RMSE")
            return rows
    except OSError as e:
        fail(f"cannot read {path}: {e.strerror}")


def plot(rows, prefix):
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        fail("plotting needs matplotlib: apt-get install python3-matplotlib (the CSV is written; "
             "--plot-only redraws from it)")
    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    presets = list(dict.fromkeys(r["Preset"] for r in rows))
    drawn = 0
    for i, preset in enumerate(presets):
        # Log axes cannot show an RMSE of 0 (an image equal to its reference) or a time of 0.
        # In spp order: at few samples the fixed cost (start-up, tree build) dominates and times
        # can come out of order; the line should still join 1, 2, 4, ... spp.
        points = sorted(((r["Seconds"], r["RMSE"], r["Spp"]) for r in rows
                         if r["Preset"] == preset and r["Seconds"] > 0 and r["RMSE"] > 0), key=lambda p: p[2])
        if not points:
            print(f"{TOOL}: {preset}: no point with a positive time and RMSE to plot", file=sys.stderr)
            continue
        colour = f"C{i % 10}"
        xs, ys, spps = zip(*points)
        ax.plot(xs, ys, "o-", color=colour, label=preset)
        for x, y, spp in points:
            ax.annotate(str(spp), (x, y), textcoords="offset points", xytext=(4, 4), fontsize=7, color=colour)
        # time^-1/2 through the first point: where the curve would go if only sampling cost time.
        guide = [ys[0] * math.sqrt(xs[0] / x) for x in xs]
        ax.plot(xs, guide, ":", color=colour, alpha=0.6, label=f"{preset}: time$^{{-1/2}}$")
        drawn += 1
    if not drawn:
        fail("nothing to plot")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("render time (s, wall clock, whole run)")
    ax.set_ylabel("RMSE against the reference")
    ax.set_title("kdrt-render: error against time (labels: samples per pixel)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    for ext in ("png", "svg"):
        fig.savefig(f"{prefix}.{ext}", dpi=120, bbox_inches="tight")
    print(f"wrote {prefix}.png and .svg")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     epilog=__doc__.split("\n\n", 2)[2],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--presets", type=lambda t: [p for p in t.split(",") if p],
                        default=["PHASE_4_REFRACTION", "PICTURE"], help="default: PHASE_4_REFRACTION,PICTURE")
    parser.add_argument("--spp", type=positive_int_list, default=[1, 2, 4, 8, 16, 32, 64],
                        help="samples per pixel to measure, default 1,2,4,8,16,32,64")
    parser.add_argument("--reference-spp", type=positive_int, default=1024,
                        help="samples per pixel of the reference, default 1024")
    parser.add_argument("--size", type=size, default="320x240", help="image size WxH, default 320x240")
    parser.add_argument("--threads", type=positive_int, help="render threads (default: the renderer's, all cores)")
    parser.add_argument("--set", type=setting, action="append", default=[], metavar="KEY=VALUE",
                        help="a setting for every render (not NSAMPLES), repeatable")
    parser.add_argument("--renderer", type=Path, default=DEFAULT_RENDERER,
                        help=f"kdrt-render binary, default {DEFAULT_RENDERER.relative_to(REPO)} in the repository")
    parser.add_argument("-o", "--output", type=Path, default=Path("rmse_vs_time"),
                        help="folder for the CSV, the plots, the references and the renders, default ./rmse_vs_time")
    parser.add_argument("--fresh-reference", action="store_true", help="render the references again")
    parser.add_argument("--plot-only", action="store_true", help="redraw the plots from DIR's CSV, render nothing")
    args = parser.parse_args()

    csv_path = args.output / CSV_NAME
    prefix = args.output / "rmse_vs_time"
    if args.plot_only:
        plot(read_csv(csv_path), prefix)
        return
    if not args.presets:
        fail("--presets names no preset")
    if max(args.spp) >= args.reference_spp:
        fail(f"the reference ({args.reference_spp} spp) must have more samples than every measured render "
             f"(up to {max(args.spp)})")
    if not (args.renderer.is_file() and os.access(args.renderer, os.X_OK)):
        fail(f"no renderer at {args.renderer}: build it (cmake --build build --target kdrt-render) "
             "or pass --renderer PATH")
    try:
        args.output.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        fail(f"cannot create {args.output}: {e.strerror}")
    rows = measure(args)
    write_csv(rows, csv_path)
    plot(rows, prefix)


if __name__ == "__main__":
    main()
