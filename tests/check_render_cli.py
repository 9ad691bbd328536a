#!/usr/bin/python3
"""kdrt-render's command line as a user meets it (tests/CMakeLists.txt registers one ctest test
per check below, render_cli_CHECK).

usage: check_render_cli.py CHECK KDRT_RENDER WORKDIR

Only the standard library: Debian's /usr/bin/python3.
"""
import os
import stat
import subprocess
import sys
import time

# A render that would take hours (65,536 samples a pixel of PICTURE): a check that must come
# before the render either comes at once or times out.
SLOW = ["--preset", "PICTURE", "--set", "NSAMPLES=65536"]


class Failure(Exception):
    pass


def check(condition, message):
    if not condition:
        raise Failure(message)


def run(command, expect_status=0, env=None, timeout=60):
    """Runs command; returns its standard error and output together. Fails on another status."""
    full_env = dict(os.environ)
    full_env.update(env or {})
    start = time.time()
    p = subprocess.run(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, env=full_env, timeout=timeout)
    out = p.stdout.decode("utf-8", "replace")
    print("$ " + " ".join(repr(c) if c == "" else c for c in command) +
          f"  -> {p.returncode} in {time.time() - start:.2f} s\n" + out, end="" if out.endswith("\n") else "\n")
    check(p.returncode == expect_status, f"exit status {p.returncode}, expected {expect_status}")
    return out


def lines_of(out):
    return [l for l in out.splitlines() if l.startswith("kdrt-render")]  # not a sanitizer's table


def write(path, text):
    with open(path, "w") as f:
        f.write(text)


def read(path):
    with open(path) as f:
        return f.read()


# ---- the checks ----

def check_outputs_first(ctx):
    """An output that cannot be written is refused before the render (here one of hours: the run
    must end within seconds): a folder of that name, a read-only file, a folder no file can be
    created in (/proc), a missing folder, and for --animate any frame's file. Status 1, one line
    "kdrt-render: cannot write 'PATH': REASON" naming the user's path, never the temporary; the
    folder and the read-only file are left as they were."""
    folder = os.path.join(ctx.work, "taken.png")
    os.makedirs(folder, exist_ok=True)
    locked = os.path.join(ctx.work, "locked.png")
    if os.path.exists(locked):
        os.chmod(locked, 0o644)
    write(locked, "the old file")
    os.chmod(locked, 0o444)
    missing = os.path.join(ctx.work, "no-such-folder", "out.exr")
    frame_folder = os.path.join(ctx.work, "anim-0001.png")  # the second frame of anim.png
    os.makedirs(frame_folder, exist_ok=True)
    cases = [
        ([folder], folder, "it exists and is not a regular file"),
        ([locked], locked, "it is read-only"),
        (["/proc/kdrt-render-test.png"], "/proc/kdrt-render-test.png", "cannot create a file in '/proc'"),
        ([missing], missing, "the folder '" + os.path.dirname(missing) + "' does not exist"),
        ([os.path.join(ctx.work, "anim.png"), "--animate", "GLASS_IOR=1:2", "--frames", "3"], frame_folder,
         "it exists and is not a regular file"),
    ]
    for args, path, reason in cases:
        out = run([ctx.render, *SLOW, "-o", *args], expect_status=1, timeout=20)
        lines = lines_of(out)
        check(len(lines) == 1, f"{path}: not one line")
        check(lines[0].startswith(f"kdrt-render: cannot write '{path}': ") and reason in lines[0],
              f"{path}: not \"cannot write '{path}': ...{reason}...\"")
        check(".tmp-" not in out, f"{path}: the message names a temporary")
    check(os.path.isdir(folder) and os.listdir(folder) == [], "the folder was changed")
    check(read(locked) == "the old file", "the read-only file was changed")
    leftovers = [n for n in os.listdir(ctx.work) if ".tmp-" in n]
    check(not leftovers and not os.path.exists(os.path.dirname(missing)), f"left behind: {leftovers}")
    os.chmod(locked, 0o644)


def check_empty_names(ctx):
    """--preset '' is refused as --preset nope is (status 2, the line naming the presets), and
    --scene '' as a missing value; neither means the default PICTURE."""
    out_png = os.path.join(ctx.work, "out.png")
    if os.path.exists(out_png):
        os.remove(out_png)
    for args, message in ((["--preset", ""], "unknown preset '' (presets: PHASE_1, "),
                          (["--preset", "nope"], "unknown preset 'nope' (presets: PHASE_1, "),
                          (["--scene", ""], "--scene needs a file")):
        out = run([ctx.render, *args, "--size", "8x6", "-o", out_png], expect_status=2)
        lines = lines_of(out)
        check(len(lines) == 1 and message in lines[0], f"{args}: no line with '{message}'")
    check(not os.path.exists(out_png), "an image was written")


def check_names_any_case(ctx):
    """Every name the renderer takes from a list ignores case: presets, settings, their true and
    false, and a scene file's material and light types and generated meshes."""
    out_png = os.path.join(ctx.work, "out.png")
    run([ctx.render, "--preset", "phase_1", "--set", "nsamples=1", "--set", "Phong=True", "--size", "8x6",
         "-o", out_png])
    scene = os.path.join(ctx.work, "cases.yaml")
    write(scene, "camera: {position: [0, 1, 4], target: [0, 0.5, 0]}\n"
                 "materials: [{name: white, type: Phong}, {name: glass, type: GLASS}, {name: chrome, type: Mirror}]\n"
                 "spheres: [{center: [0, 0.5, 0], radius: 0.5, material: glass},"
                 " {center: [1, 0.5, 0], radius: 0.3, material: chrome}]\n"
                 "meshes: [{generated: Torus, position: [-1, 0, 0], size: 0.8, material: white}]\n"
                 "lights: [{type: Sphere, center: [1, 3, 2], radius: 0.2},"
                 " {type: QUAD, corner: [0, 2, 0], edge_u: [1, 0, 0], edge_v: [0, 0, 1]}]\n")
    out = run([ctx.render, "--scene", scene, "--size", "8x6", "-o", out_png])
    check("meshes: generated torus" in out, "no torus in the summary")


def check_meshes_line_once(ctx):
    """The meshes used are named once, in the summary line."""
    out = run([ctx.render, "--preset", "PHASE_3_INTERPOLATION", "--size", "8x6", "--set", "NSAMPLES=1",
               "-o", os.path.join(ctx.work, "once.png")])
    check(sum(l.count("meshes:") for l in lines_of(out)) == 1, "not one 'meshes:'")


def check_mesh_dir_env(ctx):
    """The environment's KDRT_MESH_DIR, when set, is the mesh folder instead of the one configured
    at build time; --help says both."""
    meshes = os.path.join(ctx.work, "meshes")
    os.makedirs(os.path.join(meshes, "common"), exist_ok=True)
    for name in ("stanford-bunny", "spot"):  # PHASE_3_INTERPOLATION's two, as one triangle each
        write(os.path.join(meshes, "common", name + ".obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    out_png = os.path.join(ctx.work, "env.png")
    args = [ctx.render, "--preset", "PHASE_3_INTERPOLATION", "--size", "8x6", "--set", "NSAMPLES=1", "-o", out_png]
    out = run(args, env={"KDRT_MESH_DIR": meshes})
    check(f"meshes: {meshes}/common/stanford-bunny.obj, {meshes}/common/spot.obj, " in out,
          "the environment's folder was not used")
    os.remove(os.path.join(meshes, "common", "spot.obj"))
    out = run(args, env={"KDRT_MESH_DIR": meshes}, expect_status=1)
    check(f"no mesh named 'spot' in {meshes}/common (.obj)" in out, "no error naming the environment's folder")
    none = os.path.join(ctx.work, "no-meshes")
    out = run(args, env={"KDRT_MESH_DIR": none})
    check(f"generated torus (no mesh folder {none} for stanford-bunny)" in out, "no torus for a missing folder")
    help_text = run([ctx.render, "--help"])
    check("$KDRT_MESH_DIR, else the one configured at build time: " in help_text, "--help does not say both")


def check_exit_status(ctx):
    """0 on success, 2 for a bad command line, 1 for a failure while running, each failure with
    one line saying what was wrong."""
    out_png = os.path.join(ctx.work, "status.png")
    if os.path.exists(out_png):
        os.remove(out_png)
    bad_scene = os.path.join(ctx.work, "bad.yaml")
    write(bad_scene, "camera: [1, 2\n")
    usage = [
        ["--bogus", "-o", out_png],
        ["--size", "8x6"],  # no -o
        ["-o", os.path.join(ctx.work, "out.jpg")],
        ["--preset", "PHASE_9", "-o", out_png],
        ["--set", "NSAMPLES=many", "-o", out_png],
        ["--set", "COLOUR=red", "-o", out_png],
        ["--size", "0x10", "-o", out_png],
        ["--threads", "0", "-o", out_png],
        ["--frames", "2", "-o", out_png],
        ["--animate", "GLASS_IOR=1:x", "--frames", "2", "-o", out_png],
        ["--preset", "PHASE_1", "--scene", bad_scene, "-o", out_png],
        ["-o"],
    ]
    failures = [
        ["--scene", os.path.join(ctx.work, "no-such.yaml"), "-o", out_png],
        ["--scene", bad_scene, "-o", out_png],
        ["--preset", "PHASE_3_INTERPOLATION", "--set", "MESH=/no/such/mesh.obj", "--size", "8x6", "-o", out_png],
        ["--preset", "PHASE_1", "--size", "8x6", "--reference", os.path.join(ctx.work, "no-such.exr"), "-o", out_png],
        ["--preset", "PHASE_1", "--size", "8x6", "-o", "/no-such-folder/out.png"],
    ]
    for status, cases in ((2, usage), (1, failures)):
        for args in cases:
            lines = lines_of(run([ctx.render, *args], expect_status=status))
            check(len(lines) == 1, f"{args}: not one line")
    check(not os.path.exists(out_png), "a failed run wrote an image")
    run([ctx.render, "--preset", "PHASE_1", "--size", "8x6", "-o", out_png])
    run([ctx.render, "--help"])
    run([ctx.render, "--list-presets"])


class Context:
    def __init__(self, render, work):
        self.render, self.work = render, work


def main():
    checks = {name[len("check_"):]: f for name, f in globals().items() if name.startswith("check_") and callable(f)}
    if len(sys.argv) != 4 or sys.argv[1] not in checks:
        print(__doc__ + "\nchecks: " + " ".join(sorted(checks)), file=sys.stderr)
        return 2
    work = os.path.join(sys.argv[3], sys.argv[1])
    os.makedirs(work, exist_ok=True)
    try:
        checks[sys.argv[1]](Context(sys.argv[2], work))
    except (Failure, subprocess.TimeoutExpired) as e:
        print(f"FAILED: {e}")
        return 1
    print("passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
