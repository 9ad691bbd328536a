#!/usr/bin/python3
"""A stand-in for kdrt-render with its command line, for testing the tools/ scripts without it.

Takes the real tool's options and refuses anything else (exit 2), as the real one does. It
"renders" by sleeping 2 ms per sample per pixel (so time grows with NSAMPLES), writes a small
text file to -o, and with --reference REF prints `rmse=<value>` where the value is
0.5 / sqrt(NSAMPLES) for PHASE_4_REFRACTION and 0.8 / sqrt(NSAMPLES) for the other presets.
Each run is appended to $FAKE_KDRT_RENDER_LOG (one line of arguments) when that is set;
$FAKE_KDRT_RENDER_MODE=fail makes it fail, =no-rmse leaves out the rmse line.
"""
import math
import os
import sys
import time

PRESETS = ["PHASE_1", "PHASE_2_NO_SHADOWS", "PHASE_2_HARD_SHADOWS", "PHASE_2_SOFT_SHADOWS", "PHASE_3_REFLECTION",
           "PHASE_3_NO_INTERPOLATION", "PHASE_3_INTERPOLATION", "PHASE_4_REFRACTION", "PHASE_4_KDTREE", "PICTURE",
           "BENCHMARKS"]


def usage_error(message):
    print(f"kdrt-render: {message}", file=sys.stderr)
    sys.exit(2)


def main(argv):
    log = os.environ.get("FAKE_KDRT_RENDER_LOG")
    if log:
        with open(log, "a") as f:
            f.write(" ".join(argv) + "\n")
    options = {"--preset": None, "--scene": None, "--size": "800x600", "--threads": None, "--seed": "0",
               "--animate": None, "--frames": None, "--reference": None, "-o": None}
    settings = {}
    i = 0
    while i < len(argv):
        name = argv[i]
        if name not in options and name != "--set":
            usage_error(f"unknown option '{name}'")
        if i + 1 >= len(argv):
            usage_error(f"{name} wants a value")
        value = argv[i + 1]
        if name == "--set":
            key, sep, v = value.partition("=")
            if not sep:
                usage_error(f"--set wants KEY=VALUE, got '{value}'")
            settings[key.upper()] = v
        else:
            options[name] = value
        i += 2
    if (options["--preset"] is None) == (options["--scene"] is None):
        usage_error("give one of --preset NAME and --scene FILE")
    if options["--preset"] is not None and options["--preset"] not in PRESETS:
        print(f"kdrt-render: unknown preset '{options['--preset']}'", file=sys.stderr)
        return 1
    out = options["-o"]
    if not out or not out.lower().endswith((".png", ".exr")):
        usage_error("-o wants OUT.png or OUT.exr")
    w, _, h = options["--size"].partition("x")
    if not (w.isdigit() and h.isdigit()):
        usage_error(f"--size wants WxH, got '{options['--size']}'")
    nsamples = int(settings.get("NSAMPLES", "1"))
    reference = options["--reference"]
    if reference is not None and not os.path.isfile(reference):
        print(f"kdrt-render: cannot read the reference '{reference}'", file=sys.stderr)
        return 1
    if os.environ.get("FAKE_KDRT_RENDER_MODE") == "fail":
        print("kdrt-render: out of luck (FAKE_KDRT_RENDER_MODE=fail)", file=sys.stderr)
        return 1
    time.sleep(0.002 * nsamples)
    with open(out, "w") as f:
        f.write(f"fake image {w}x{h} at {nsamples} spp\n")
    if reference is not None and os.environ.get("FAKE_KDRT_RENDER_MODE") != "no-rmse":
        base = 0.5 if options["--preset"] == "PHASE_4_REFRACTION" else 0.8
        print(f"rmse={base / math.sqrt(nsamples):.9g}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
