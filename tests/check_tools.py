#!/usr/bin/python3
"""Tests of the programs' command lines and the scripts around them:

- ExitStatus: every program (kdrt-render, kdrt-view, kdrt-bench, kdrt-inspect, kdrt-construction,
  kdrt-render-mesh, kdrt-ray-costs) exits 0 for --help, 2 for a bad command line with one line
  saying what was wrong, and 1 for a failure (a bad input file, an output it cannot write).
- OutputsFirst: kdrt-inspect, kdrt-construction and kdrt-render-mesh refuse an output they cannot
  write before the work, in one line naming the path and the reason; kdrt-render-mesh refuses
  a name it cannot write (out.jpg); enumerated values (--builder SAH) are taken in any case.
- MeshFolder: the environment's KDRT_MESH_DIR names the mesh folder of kdrt-inspect,
  kdrt-render-mesh and kdrt-ray-costs, and their --help says so.
- SetupScript: tools/setup.sh waits for a held apt or dpkg lock and passes apt-get its lock
  timeout (against stand-ins for dpkg-query, sudo and apt-get, with locks of the test's own).
- RmseVsTime, FramesToVideo, QualityTable, BatchTable: examples/render/rmse_vs_time.py (against
  tests/fake_kdrt_render.py, which has kdrt-render's command line), examples/render/
  frames_to_video.sh (on frames ffmpeg makes, when ffmpeg is installed), bench/quality_table.py
  and bench/batch_table.py (on small CSVs written here).

usage: tests/check_tools.py [TEST ...] [PROGRAM=PATH ...]
  TEST: a unittest name (ExitStatus, ExitStatus.test_kdrt_inspect, ...; default: all)
  PROGRAM=PATH: where a program is (kdrt-inspect=build/tools/kdrt-inspect); the tests of a
  program not given are skipped
"""
import csv
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
import unittest
from pathlib import Path

HERE = Path(__file__).resolve().parent
TOOLS = HERE.parent / "examples" / "render"
BENCH = HERE.parent / "bench"
FAKE = HERE / "fake_kdrt_render.py"
SETUP = HERE.parent / "tools" / "setup.sh"
PROGRAMS = {}  # name -> path, from the NAME=PATH arguments


def run(command, env=None, stdout=subprocess.PIPE, timeout=None):
    return subprocess.run([str(c) for c in command], stdout=stdout, stderr=subprocess.PIPE, text=True,
                          env={**os.environ, **(env or {})}, timeout=timeout)


OCTAHEDRON = ("OFF\n6 8 0\n1 0 0\n-1 0 0\n0 1 0\n0 -1 0\n0 0 1\n0 0 -1\n"
              "3 0 2 4\n3 2 1 4\n3 1 3 4\n3 3 0 4\n3 2 0 5\n3 1 2 5\n3 3 1 5\n3 0 3 5\n")


class ProgramTest(unittest.TestCase):
    """A folder with an octahedron, a folder named like an output file, a read-only file, and a
    way to run a program given as NAME=PATH and check its status and its message."""

    def setUp(self):
        self.dir = Path(tempfile.mkdtemp(prefix="kdrt_programs_test_"))
        self.mesh = self.dir / "octahedron.off"
        self.mesh.write_text(OCTAHEDRON)
        self.missing = self.dir / "no-such-file.obj"
        self.folder = self.dir / "a-folder"
        self.folder.mkdir()

    def tearDown(self):
        shutil.rmtree(self.dir, ignore_errors=True)

    def folder_named(self, name):
        (self.dir / name).mkdir()
        return self.dir / name

    def read_only(self, name):
        path = self.dir / name
        path.write_bytes(b"old")
        path.chmod(0o444)
        return path

    def program(self, name):
        if name not in PROGRAMS:
            self.skipTest(f"{name} not given (as {name}=PATH)")
        return PROGRAMS[name]

    def check(self, name, args, status, message=None, one_line=False, env=None, stdout=subprocess.PIPE):
        """Runs program `name` with args; its status must be `status` and a line of its stderr must
        match "NAME: MESSAGE" (a regular expression), the only line if one_line."""
        done = run([self.program(name), *args], env=env, stdout=stdout, timeout=60)
        shown = f"{name} {' '.join(map(str, args))}: exit {done.returncode}\n{done.stderr}"
        self.assertEqual(done.returncode, status, shown)
        lines = done.stderr.splitlines()
        if one_line:
            self.assertEqual(len(lines), 1, shown)
        if message is not None:
            self.assertTrue(any(re.fullmatch(f"{re.escape(name)}: {message}", line) for line in lines),
                            f"no line matches '{name}: {message}' in\n{shown}")
        return done

    def check_usage(self, name, args, message=".+"):
        """A bad command line: status 2 and one line saying what was wrong, nothing on stdout."""
        done = self.check(name, args, 2, message, one_line=True)
        self.assertEqual(done.stdout, "")

    def check_help(self, name):
        done = self.check(name, ["--help"], 0)
        self.assertIn("usage: " + name, done.stdout)


class ExitStatus(ProgramTest):
    """0 for --help, 2 for a bad command line (a bad option, a missing value or required argument),
    1 for a failure (an input file it cannot read, an output it cannot write); each program's
    test runs each case. The programs of tools/, kdrt-render-mesh and kdrt-ray-costs also say
    "PROGRAM: cannot read|write 'PATH': REASON" in one line."""

    def read_failure(self, name, args, path):
        self.check(name, args, 1, f"cannot read '{re.escape(str(path))}': .+", one_line=True)

    def write_failure(self, name, args, path):
        self.check(name, args, 1, f"cannot write '{re.escape(str(path))}': .+", one_line=True)

    def test_kdrt_render(self):
        name = "kdrt-render"
        self.check_help(name)
        self.check_usage(name, ["--bogus"])
        self.check_usage(name, ["--preset", "PHASE_1", "--size", "8x6"])  # no -o
        self.check_usage(name, ["--size"])
        out = self.dir / "out.png"
        self.check(name, ["--set", f"MESH={self.missing}", "--size", "8x6", "-o", out], 1, f".*{re.escape(str(self.missing))}.*")
        folder = self.folder_named("folder.png")
        self.check(name, ["--preset", "PHASE_1", "--size", "8x6", "-o", folder], 1, f".*{re.escape(str(folder))}.*")

    def test_kdrt_view(self):
        name = "kdrt-view"
        self.check_help(name)
        self.check_usage(name, ["--bogus"])
        self.check_usage(name, ["--size"])
        offscreen = {"SDL_VIDEODRIVER": "offscreen"}
        scene = self.dir / "no-such-scene.yaml"
        self.check(name, ["--scene", scene, "--frames", "1", "--size", "8x6"], 1, f".*{re.escape(str(scene))}.*",
                   env=offscreen)
        folder = self.folder_named("folder.png")
        self.check(name, ["--preset", "PHASE_1", "--frames", "1", "--size", "8x6", "--screenshot", folder], 1,
                   f".*{re.escape(str(folder))}.*", env=offscreen)

    def test_kdrt_bench(self):
        name = "kdrt-bench"
        self.check_help(name)
        self.check_usage(name, ["--bogus"])
        self.check_usage(name, ["--size"])
        out = self.dir / "out.csv"
        self.check(name, ["--size", "8x8", "--leaf-sizes", "1", self.missing, "-o", out], 1,
                   f".*{re.escape(str(self.missing))}.*")
        folder = self.folder_named("folder.csv")
        self.check(name, ["--size", "8x8", "--leaf-sizes", "1", self.mesh, "-o", folder], 1, f".*{re.escape(str(folder))}.*")

    def test_kdrt_inspect(self):
        name = "kdrt-inspect"
        self.check_help(name)
        self.check_usage(name, ["--bogus"], "unknown option '--bogus' \\(see --help\\)")
        self.check_usage(name, [self.mesh, "--boxes"], "--boxes needs a value \\(see --help\\)")
        self.check_usage(name, [self.mesh, "--depth", "65"], "--depth wants a whole number from 0 to 64, not '65'")
        self.check_usage(name, [self.mesh, "--boxes", self.dir / "boxes.stl"], ".*'.*boxes.stl'")
        self.read_failure(name, [self.missing], self.missing)
        self.read_failure(name, [self.folder], self.folder)
        folder = self.folder_named("folder.obj")
        self.write_failure(name, [self.mesh, "--boxes", folder], folder)

    def test_kdrt_construction(self):
        name = "kdrt-construction"
        self.check_help(name)
        self.check_usage(name, ["--bogus"], "unknown option '--bogus' \\(see --help\\)")
        self.check_usage(name, [], "no output: give -o OUT.json .*")
        self.check_usage(name, ["-o"], "-o needs a value \\(see --help\\)")
        self.check_usage(name, ["--count", "0", "-o", "-"], "--count wants a whole number from 1 to 10000, not '0'")
        missing = self.dir / "no-such-file.txt"
        self.read_failure(name, [missing, "-o", "-"], missing)
        self.read_failure(name, [self.folder, "-o", "-"], self.folder)
        folder = self.folder_named("folder.json")
        self.write_failure(name, ["-o", folder], folder)

    def test_kdrt_render_mesh(self):
        name = "kdrt-render-mesh"
        self.check_help(name)
        self.check_usage(name, ["--bogus"], "unknown option '--bogus' \\(see --help\\)")
        self.check_usage(name, [self.mesh], "no output file: give -o OUT.png")
        self.check_usage(name, [self.mesh, "-o"], "-o needs a value \\(see --help\\)")
        self.check_usage(name, [self.mesh, "--size", "8x0", "-o", self.dir / "out.png"], "bad --size '8x0': .+")
        self.read_failure(name, [self.missing, "-o", self.dir / "out.png"], self.missing)
        self.read_failure(name, [self.folder, "-o", self.dir / "out.png"], self.folder)
        folder = self.folder_named("folder.png")
        self.write_failure(name, [self.mesh, "--size", "8x6", "-o", folder], folder)

    def test_kdrt_ray_costs(self):
        name = "kdrt-ray-costs"
        self.check_help(name)
        self.check_usage(name, ["--bogus"], "unknown option '--bogus' \\(see --help\\)")
        self.check_usage(name, ["--size"], "--size needs a value \\(see --help\\)")
        self.check_usage(name, ["--repeat", "0"], "--repeat wants 1 to 1000, got '0'")
        self.read_failure(name, [self.missing], self.missing)
        self.read_failure(name, [self.folder], self.folder)
        # Its one output is standard output: a full disk is a failure.
        with open("/dev/full", "w") as full:
            self.check(name, ["--size", "8x8", "--repeat", "1", self.mesh], 1,
                       "cannot write standard output: No space left on device", one_line=True, stdout=full)


class OutputsFirst(ProgramTest):
    """An output a program cannot write is refused before the work: status 1, one line naming the
    user's path and the reason, no report on stdout and no build or trace on stderr."""

    def outputs(self):
        """(program, arguments with OUT for the output) for each output of each program."""
        return [("kdrt-inspect", [self.mesh, "--boxes", "OUT.obj"]),
                ("kdrt-inspect", [self.mesh, "--picture", "OUT.png", "--size", "64x48"]),
                ("kdrt-construction", ["-o", "OUT.json"]),
                ("kdrt-render-mesh", [self.mesh, "--size", "64x48", "-o", "OUT.png"])]

    def refused(self, kind, make):
        for name, args in self.outputs():
            with self.subTest(program=name, output=args[-1] if args[-1].startswith("OUT") else args[-3], kind=kind):
                ext = next(a for a in args if isinstance(a, str) and a.startswith("OUT"))[3:]
                path = make(f"{name}-{kind}{ext}")
                done = self.check(name, [path if a == "OUT" + ext else a for a in args], 1,
                                  f"cannot write '{re.escape(str(path))}': .+", one_line=True)
                self.assertEqual(done.stdout, "")

    def test_a_folder(self):
        self.refused("folder", self.folder_named)

    def test_a_read_only_file(self):
        self.refused("read-only", self.read_only)
        for path in self.dir.glob("*read-only*"):
            self.assertEqual(path.read_bytes(), b"old")

    def test_a_path_that_cannot_be_created(self):
        self.refused("uncreatable", lambda name: self.dir / "no-such-folder" / name)

    def test_render_mesh_writes_png_only(self):
        jpg = self.dir / "out.jpg"
        self.check_usage("kdrt-render-mesh", [self.mesh, "--size", "8x6", "-o", jpg],
                         f"cannot write '{re.escape(str(jpg))}': .*PNG.*")
        self.assertFalse(jpg.exists())
        png = self.dir / "OUT.PNG"
        self.check("kdrt-render-mesh", [self.mesh, "--size", "8x6", "-o", png], 0)
        self.assertEqual(png.read_bytes()[:8], b"\x89PNG\r\n\x1a\n")

    def test_builders_in_any_case(self):
        done = self.check("kdrt-inspect", [self.mesh, "--builder", "SAH", "--json"], 0)
        self.assertIn('"builder": "sah"', done.stdout)
        done = self.check("kdrt-inspect", [self.mesh, "--builder", "Median", "--json"], 0)
        self.assertIn('"builder": "median"', done.stdout)
        self.check_usage("kdrt-inspect", [self.mesh, "--builder", "kd"], "--builder wants median or sah, not 'kd'")
        for builder in ("MEDIAN", "Sah"):
            done = self.check("kdrt-construction", ["--builder", builder, "-o", "-"], 0)
            self.assertIn(f'"builder": "{builder.lower()}"', done.stdout)


class MeshFolder(ProgramTest):
    """The mesh folder is the environment's KDRT_MESH_DIR when it is set, else the one configured
    at build time, and --help says so: here a folder whose bunny and nefertiti are octahedra."""

    def setUp(self):
        super().setUp()
        self.meshes = self.dir / "meshes"
        obj = "".join(f"v {line}\n" for line in OCTAHEDRON.splitlines()[2:8]) + "".join(
            "f " + " ".join(str(int(i) + 1) for i in line.split()[1:]) + "\n" for line in OCTAHEDRON.splitlines()[8:])
        for name, text in (("common/stanford-bunny.obj", obj), ("seed/nefertiti.off", OCTAHEDRON)):
            (self.meshes / name).parent.mkdir(parents=True, exist_ok=True)
            (self.meshes / name).write_text(text)
        self.env = {"KDRT_MESH_DIR": str(self.meshes)}

    def test_help_names_the_variable(self):
        for name in ("kdrt-inspect", "kdrt-render-mesh", "kdrt-ray-costs"):
            with self.subTest(program=name):
                done = self.check(name, ["--help"], 0)
                self.assertIn("The mesh folder: $KDRT_MESH_DIR, else the one configured at build time: ", done.stdout)

    def test_the_environment_names_the_folder(self):
        bunny = self.meshes / "common" / "stanford-bunny.obj"
        done = self.check("kdrt-inspect", ["--json"], 0, env=self.env)
        self.assertIn(f'"source": "{bunny}, the default"', done.stdout)
        self.assertIn('"input_triangles": 8', done.stdout)
        out = self.dir / "bunny.png"
        done = self.check("kdrt-render-mesh", ["--size", "8x6", "-o", out], 0, env=self.env)
        self.assertIn(f"mesh: {bunny}\n", done.stderr)
        done = self.check("kdrt-ray-costs", ["--size", "8x8", "--repeat", "1"], 0, env=self.env)
        # A line naming the kernel, then two tables, the rays' and the batches', each naming the
        # default meshes.
        parts = done.stdout.strip().split("\n\n")
        self.assertRegex(parts[0], r"^Kernel: (scalar|avx2|avx512) \(--kernel default\)\.$")
        tables = parts[1:]
        self.assertEqual(len(tables), 2)
        for table in tables:
            self.assertEqual(sorted({line.split("|")[1].strip() for line in table.splitlines()[2:]}),
                             ["nefertiti", "stanford-bunny"])


# Holds a POSIX lock (as apt and dpkg take theirs) on argv[1] for argv[2] seconds, says "held" on
# stdout once it has it, and writes "released NAME" to the log argv[3] just before letting go.
LOCK_HOLDER = """
import fcntl, os, sys, time
lock = open(sys.argv[1], "a")
fcntl.lockf(lock, fcntl.LOCK_EX)
print("held", flush=True)
time.sleep(float(sys.argv[2]))
with open(sys.argv[3], "a") as log:
    log.write("released " + os.path.basename(sys.argv[1]) + "\\n")
"""


class SetupScript(unittest.TestCase):
    """tools/setup.sh with every package missing (a stand-in dpkg-query), through stand-ins for
    sudo and apt-get (which logs its arguments), with lock files of its own: this machine's apt is
    neither run nor locked."""

    def setUp(self):
        self.dir = Path(tempfile.mkdtemp(prefix="kdrt_setup_test_"))
        self.log = self.dir / "log"
        bin_dir = self.dir / "bin"
        bin_dir.mkdir()
        for tool, body in {"dpkg-query": "exit 1",
                           "sudo": 'exec "$@"',
                           "apt-get": f'echo "apt-get $*" >> "{self.log}"'}.items():
            (bin_dir / tool).write_text(f"#!/bin/sh\n{body}\n")
            (bin_dir / tool).chmod(0o755)
        self.locks = {}
        self.env = {"PATH": f"{bin_dir}:{os.environ.get('PATH', '/usr/bin:/bin')}"}
        for name, variable in (("lists", "KDRT_SETUP_LISTS_LOCK"), ("lock-frontend", "KDRT_SETUP_DPKG_LOCK"),
                               ("lock", "KDRT_SETUP_DPKG_LOCK_INNER"), ("archives", "KDRT_SETUP_ARCHIVES_LOCK")):
            self.locks[name] = self.dir / name
            self.locks[name].touch()
            self.env[variable] = str(self.locks[name])
        self.holders = []

    def tearDown(self):
        for holder in self.holders:
            holder.kill()
            holder.wait()
            holder.stdout.close()
        shutil.rmtree(self.dir, ignore_errors=True)

    def hold(self, name, seconds):
        holder = subprocess.Popen([sys.executable, "-c", LOCK_HOLDER, self.locks[name], str(seconds), self.log],
                                  stdout=subprocess.PIPE, text=True)
        self.holders.append(holder)
        self.assertEqual(holder.stdout.readline(), "held\n")
        return holder

    def setup(self, *args):
        return run(["bash", SETUP, *args], env=self.env, timeout=60)

    def logged(self):
        return self.log.read_text().splitlines() if self.log.exists() else []

    def test_apt_get_is_given_a_lock_timeout(self):
        done = self.setup()
        self.assertEqual(done.returncode, 0, done.stderr)
        update, install = self.logged()
        self.assertEqual(update, "apt-get -o DPkg::Lock::Timeout=600 update")
        self.assertTrue(install.startswith("apt-get -o DPkg::Lock::Timeout=600 install -y --no-install-recommends cmake "),
                        install)
        done = self.setup("--lock-timeout", "30")
        self.assertEqual(done.returncode, 0, done.stderr)
        self.assertEqual(self.logged()[2], "apt-get -o DPkg::Lock::Timeout=30 update")
        self.assertEqual(self.setup("--lock-timeout", "soon").returncode, 2)

    def test_it_waits_for_a_held_dpkg_lock_and_says_so(self):
        holder = self.hold("lock-frontend", 2)
        done = self.setup("--lock-timeout", "30")
        self.assertEqual(done.returncode, 0, done.stderr)
        self.assertIn(f"setup.sh: waiting for the lock {self.locks['lock-frontend']}, held by process {holder.pid} "
                      "(python3) (up to 30 s) ...", done.stdout)
        # apt-get install ran only once the lock was free.
        self.assertEqual([line.split(" install ")[0] for line in self.logged()],
                         ["apt-get -o DPkg::Lock::Timeout=30 update", "released lock-frontend",
                          "apt-get -o DPkg::Lock::Timeout=30"])

    def test_it_waits_for_the_package_lists(self):
        self.hold("lists", 2)
        done = self.setup("--lock-timeout", "30")
        self.assertEqual(done.returncode, 0, done.stderr)
        self.assertIn(f"waiting for the lock {self.locks['lists']}", done.stdout)
        self.assertEqual(self.logged()[:2], ["released lists", "apt-get -o DPkg::Lock::Timeout=30 update"])

    def test_a_lock_held_too_long_stops_it(self):
        holder = self.hold("archives", 60)
        done = self.setup("--lock-timeout", "1")
        self.assertEqual(done.returncode, 1)
        self.assertIn(f"setup.sh: cannot install: {self.locks['archives']} is still locked by process {holder.pid} "
                      "(python3) after 1 s", done.stderr)
        self.assertEqual(self.logged(), ["apt-get -o DPkg::Lock::Timeout=1 update"])  # no install


class RmseVsTime(unittest.TestCase):
    def setUp(self):
        self.dir = Path(tempfile.mkdtemp(prefix="kdrt_rmse_test_"))
        self.out = self.dir / "out"
        self.log = self.dir / "renders.log"

    def tearDown(self):
        shutil.rmtree(self.dir, ignore_errors=True)

    def tool(self, *extra, env=None, renderer=FAKE):
        return run([sys.executable, TOOLS / "rmse_vs_time.py", "--renderer", renderer, "--spp", "1,4,16",
                    "--reference-spp", "64", "--size", "8x6", "-o", self.out, *extra],
                   env={"FAKE_KDRT_RENDER_LOG": str(self.log), **(env or {})})

    def logged(self):
        return self.log.read_text().splitlines() if self.log.exists() else []

    def test_measures_every_preset_and_spp_and_caches_the_reference(self):
        done = self.tool("--threads", "2", "--set", "MAX_BOUNCES=3")
        self.assertEqual(done.returncode, 0, done.stderr)
        with open(self.out / "rmse_vs_time.csv", newline="") as f:
            rows = list(csv.reader(f, delimiter=";"))
        self.assertEqual(rows[0], ["Preset", "Spp", "Seconds", "RMSE"])
        self.assertEqual([(r[0], int(r[1])) for r in rows[1:]],
                         [("PHASE_4_REFRACTION", 1), ("PHASE_4_REFRACTION", 4), ("PHASE_4_REFRACTION", 16),
                          ("PICTURE", 1), ("PICTURE", 4), ("PICTURE", 16)])
        for preset, spp, seconds, rmse in rows[1:]:
            base = 0.5 if preset == "PHASE_4_REFRACTION" else 0.8  # what the fake prints
            self.assertAlmostEqual(float(rmse), base / math.sqrt(int(spp)), places=7)
            self.assertGreater(float(seconds), 0.002 * int(spp))  # at least the fake's sleep
        for ext in ("png", "svg"):
            self.assertGreater((self.out / f"rmse_vs_time.{ext}").stat().st_size, 1000)
        self.assertTrue((self.out / "rmse_vs_time.svg").read_text().lstrip().startswith("<?xml"))

        runs = self.logged()
        references = [r for r in runs if "--reference" not in r]
        measured = [r for r in runs if "--reference" in r]
        self.assertEqual(len(references), 2)
        for r in references:
            self.assertIn("--set NSAMPLES=64", r)
            self.assertIn("--seed 2", r)  # not the measured renders' seed
            self.assertIn("--set MAX_BOUNCES=3", r)
        self.assertEqual(len(measured), 6)
        for r in measured:
            self.assertIn("--seed 1", r)
            self.assertIn("--threads 2", r)
            self.assertIn("--size 8x6", r)
            self.assertIn("--set MAX_BOUNCES=3", r)
            self.assertRegex(r, r"--reference \S*reference-(PHASE_4_REFRACTION|PICTURE)-8x6-64spp-MAX_BOUNCES=3\.exr")

        # Again: the references are reused, only the six measured renders run.
        self.log.unlink()
        done = self.tool("--threads", "2", "--set", "MAX_BOUNCES=3")
        self.assertEqual(done.returncode, 0, done.stderr)
        self.assertIn("(cached)", done.stderr)
        self.assertEqual(len([r for r in self.logged() if "--reference" not in r]), 0)
        self.assertEqual(len(self.logged()), 6)

        # --plot-only redraws from the CSV and renders nothing.
        self.log.unlink()
        (self.out / "rmse_vs_time.png").unlink()
        done = self.tool("--plot-only")
        self.assertEqual(done.returncode, 0, done.stderr)
        self.assertTrue((self.out / "rmse_vs_time.png").exists())
        self.assertEqual(self.logged(), [])

    def test_a_failing_renderer_stops_the_run_with_its_message(self):
        done = self.tool(env={"FAKE_KDRT_RENDER_MODE": "fail"})
        self.assertEqual(done.returncode, 1)
        self.assertIn("rmse_vs_time: the renderer failed (exit 1)", done.stderr)
        self.assertIn("out of luck", done.stderr)
        self.assertFalse((self.out / "rmse_vs_time.csv").exists())

    def test_a_renderer_without_an_rmse_line_is_an_error(self):
        done = self.tool(env={"FAKE_KDRT_RENDER_MODE": "no-rmse"})
        self.assertEqual(done.returncode, 1)
        self.assertIn("PHASE_4_REFRACTION at 1 spp: no 'rmse=<number >= 0>' line", done.stderr)

    def test_bad_options_are_refused_before_rendering(self):
        done = self.tool(renderer=self.dir / "no-such-renderer")
        self.assertEqual(done.returncode, 1)
        self.assertIn("no renderer at", done.stderr)
        done = self.tool("--spp", "1,x")
        self.assertEqual(done.returncode, 2)
        self.assertIn("--spp: wants positive whole numbers", done.stderr)
        done = self.tool("--reference-spp", "16")
        self.assertEqual(done.returncode, 1)
        self.assertIn("must have more samples than every measured render", done.stderr)
        done = self.tool("--set", "NSAMPLES=4")
        self.assertEqual(done.returncode, 2)
        self.assertIn("NSAMPLES is what this tool varies", done.stderr)
        done = self.tool("--size", "8by6")
        self.assertEqual(done.returncode, 2)
        self.assertEqual(self.logged(), [])
        done = self.tool("--presets", "NOT_A_PRESET")
        self.assertEqual(done.returncode, 1)
        self.assertIn("unknown preset 'NOT_A_PRESET'", done.stderr)


class FramesToVideo(unittest.TestCase):
    def setUp(self):
        self.dir = Path(tempfile.mkdtemp(prefix="kdrt_video_test_"))

    def tearDown(self):
        shutil.rmtree(self.dir, ignore_errors=True)

    def tool(self, *args, env=None):
        return run(["bash", TOOLS / "frames_to_video.sh", *args], env=env)

    def test_without_ffmpeg_it_says_so(self):
        done = self.tool(self.dir / "anim.png", self.dir / "anim.mp4", env={"FFMPEG": str(self.dir / "no-ffmpeg")})
        self.assertEqual(done.returncode, 1)
        self.assertIn("ffmpeg not found", done.stderr)
        self.assertIn("apt-get install ffmpeg", done.stderr)

    @unittest.skipUnless(shutil.which("ffmpeg") and shutil.which("ffprobe"), "ffmpeg is not installed")
    def test_frames_become_a_video_and_a_gap_is_refused(self):
        # 7 frames of ffmpeg's test pattern, odd-sized like a --size 33x25 render, named as
        # kdrt-render -o anim.png --animate ... --frames 7 names them.
        made = run(["ffmpeg", "-hide_banner", "-loglevel", "error", "-f", "lavfi", "-i", "testsrc=size=33x25:rate=10",
                    "-frames:v", "7", "-start_number", "0", self.dir / "anim-%04d.png"])
        self.assertEqual(made.returncode, 0, made.stderr)
        video = self.dir / "anim.mp4"
        done = self.tool(self.dir / "anim.png", video, "--fps", "12")
        self.assertEqual(done.returncode, 0, done.stderr)
        self.assertIn("7 frames at 12 fps", done.stdout)
        probe = run(["ffprobe", "-v", "error", "-count_frames", "-select_streams", "v:0", "-show_entries",
                     "stream=codec_name,width,height,nb_read_frames,r_frame_rate", "-of", "csv=p=0", video])
        self.assertEqual(probe.stdout.strip(), "h264,34,26,12/1,7")  # padded to even sides

        (self.dir / "anim-0003.png").unlink()
        gap_video = self.dir / "gap.mp4"
        done = self.tool(self.dir / "anim", gap_video)
        self.assertEqual(done.returncode, 1)
        self.assertIn("anim-0003.png is missing (6 numbered frames are there)", done.stderr)
        self.assertFalse(gap_video.exists())
        self.assertEqual(sorted(p.name for p in self.dir.iterdir() if "partial" in p.name), [])

        done = self.tool(self.dir / "anim", video, "--fps", "0")
        self.assertEqual(done.returncode, 1)
        self.assertIn("--fps wants a positive number", done.stderr)
        done = self.tool(self.dir / "none", video)
        self.assertEqual(done.returncode, 1)
        self.assertIn("no first frame", done.stderr)


class QualityTable(unittest.TestCase):
    HEADER = ("Mesh;MaxLeafSize;ElapsedMs;Builder;Triangles;BuildMs;TraceMs;MRaysPerSec;Nodes;Leaves;MaxDepth;"
              "AvgLeafTriangles;TreeBytes;Mismatches;ReferenceRays;Intersector;SahCost;SahCosts;BuildThreads;Quality;Query;Start")

    def setUp(self):
        self.dir = Path(tempfile.mkdtemp(prefix="kdrt_quality_test_"))

    def tearDown(self):
        shutil.rmtree(self.dir, ignore_errors=True)

    def csv(self, name, rows):
        path = self.dir / name
        path.write_text(self.HEADER + "\n" + "\n".join(rows) + "\n")
        return path

    @staticmethod
    def row(builder, quality, build_ms, mrays, threads=1, mismatches=0):
        kd = builder == "sah"
        return (f"BALL;{4 if kd else -1};1;{builder};1000;{build_ms};1;{mrays};{'10;5;3;8.00;80000' if kd else ';;;;'};"
                f"{mismatches};100;{'watertight' if kd else ''};{'500.000' if kd else ''};{'30:20:0.1' if kd else ''};"
                f"{threads};{quality};{'plain' if kd else ''};{'root' if kd else ''}")

    def test_levels_beside_embree_medians_and_ratios(self):
        r = self.row
        primary = self.csv("p.csv", [r("sah", "fast", 2, 8), r("sah", "fast", 4, 8), r("sah", "fast", 3, 9),
                                     r("sah", "high", 12, 10), r("embree", "low", 1, 9), r("embree", "medium", 4, 9)])
        diffuse = self.csv("d.csv", [r("sah", "fast", 3, 4, mismatches=2), r("sah", "high", 12, 5),
                                     r("embree", "low", 1, 9), r("embree", "medium", 4, 9)])
        two = self.csv("t.csv", [r("sah", "fast", 2, 1, threads=2), r("sah", "high", 6, 1, threads=2),
                                 r("embree", "low", 0.5, 1, threads=2), r("embree", "medium", 2, 1, threads=2)])
        done = run([sys.executable, BENCH / "quality_table.py", "--primary", primary, "--diffuse", diffuse,
                    "--two-threads", two])
        self.assertEqual(done.returncode, 0, done.stderr)
        lines = [line for line in done.stdout.splitlines() if line.startswith("| BALL")]
        self.assertEqual(len(lines), 2)  # FAST and HIGH: MEDIUM was not measured
        fast = [c.strip() for c in lines[0].split("|")[1:-1]]
        # Build: the median of 2, 4, 3, 3 ms; over Embree LOW's 1 and MEDIUM's 4.
        self.assertEqual(fast[2:6], ["FAST", "3.0 (3.0x LOW, 0.8x MEDIUM)", "2.0 (4.0x LOW, 1.0x MEDIUM)", "1.50x"])
        self.assertEqual(fast[6:8], ["8.00 (0.80x)", "4.00 (0.80x)"])  # primary median 8 of HIGH's 10
        self.assertEqual(fast[-1], "2")  # mismatches summed
        high = [c.strip() for c in lines[1].split("|")[1:-1]]
        self.assertEqual(high[3], "12.0 (3.0x MEDIUM)")
        self.assertEqual(high[6], "10.00 (1.00x)")

    def test_a_csv_without_the_quality_column_is_refused(self):
        old = self.dir / "old.csv"
        # The columns before Quality: a CSV from a kdrt-bench older than --quality.
        old.write_text(self.HEADER.rsplit(";", 3)[0] + "\n" + self.row("sah", "fast", 1, 1).rsplit(";", 3)[0] + "\n")
        done = run([sys.executable, BENCH / "quality_table.py", "--primary", old, "--diffuse", old, "--two-threads", old])
        self.assertNotEqual(done.returncode, 0)
        self.assertIn("no Quality column", done.stderr)


class BatchTable(unittest.TestCase):
    HEADER = QualityTable.HEADER + ";Call"

    def setUp(self):
        self.dir = Path(tempfile.mkdtemp(prefix="kdrt_batch_test_"))

    def tearDown(self):
        shutil.rmtree(self.dir, ignore_errors=True)

    def csv(self, name, rows):
        path = self.dir / name
        path.write_text(self.HEADER + "\n" + "\n".join(rows) + "\n")
        return path

    @staticmethod
    def row(builder, call, mrays, leaf=4, query="plain", mismatches=0):
        kd = builder == "sah"
        return (f"BALL;{leaf if kd else -1};1;{builder};1000;1;1;{mrays};{'10;5;3;8.00;80000' if kd else ';;;;'};"
                f"{mismatches};100;{'watertight' if kd else ''};{'500.000' if kd else ''};{'30:20:0.1' if kd else ''};"
                f"1;{'default' if kd else 'medium'};{query if kd else ''};{'root' if kd else ''};{call}")

    def test_calls_side_by_side_medians_and_ratios(self):
        r = self.row
        primary = self.csv("p.csv", [r("sah", "single", 4), r("sah", "single", 6), r("sah", "batch", 6, mismatches=1),
                                     r("sah", "batch", 1, query="filter"), r("embree", "single", 8),
                                     r("embree", "batch", 9), r("embree", "packet8", 10), r("embree", "packet16", 12)])
        done = run([sys.executable, BENCH / "batch_table.py", f"primary, 4x2 tiles={primary}"])
        self.assertEqual(done.returncode, 0, done.stderr)
        lines = [line for line in done.stdout.splitlines() if line.startswith("| BALL")]
        self.assertEqual(len(lines), 1)
        cells = [c.strip() for c in lines[0].split("|")[1:-1]]
        # kdrt: the median of 4 and 6, the filter row left out; batch over Embree's fastest, 12.
        self.assertEqual(cells, ["BALL", "1,000", "primary, 4x2 tiles", "5.00", "6.00", "1.20x", "8.00", "9.00",
                                 "10.00", "12.00", "0.50x", "1"])

    def test_a_csv_of_two_trees_is_refused(self):
        two = self.csv("two.csv", [self.row("sah", "single", 4, leaf=1), self.row("sah", "single", 4, leaf=4)])
        done = run([sys.executable, BENCH / "batch_table.py", f"primary={two}"])
        self.assertNotEqual(done.returncode, 0)
        self.assertIn("2 kinds of sah build", done.stderr)
        done = run([sys.executable, BENCH / "batch_table.py", str(two)])
        self.assertNotEqual(done.returncode, 0)
        self.assertIn("want LABEL=CSV", done.stderr)


if __name__ == "__main__":
    tests = []
    for arg in sys.argv[1:]:
        name, is_program, path = arg.partition("=")
        if is_program:
            PROGRAMS[name] = path
        else:
            tests.append(arg)
    unittest.main(argv=[sys.argv[0], *tests], verbosity=2)
