#!/usr/bin/python3
"""Tests of examples/render/rmse_vs_time.py (against tests/fake_kdrt_render.py, which has kdrt-render's
command line), examples/render/frames_to_video.sh (on frames ffmpeg makes, when ffmpeg is installed)
and bench/quality_table.py (on small CSVs written here).

usage: tests/check_tools.py [RmseVsTime | FramesToVideo | QualityTable]   (unittest names; default: all)
"""
import csv
import math
import os
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


def run(command, env=None):
    return subprocess.run([str(c) for c in command], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                          env={**os.environ, **(env or {})})


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
              "AvgLeafTriangles;TreeBytes;Mismatches;ReferenceRays;Intersector;SahCost;SahCosts;BuildThreads;Quality;Query")

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
                f"{threads};{quality};{'plain' if kd else ''}")

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
        old.write_text(self.HEADER.rsplit(";", 2)[0] + "\n" + self.row("sah", "fast", 1, 1).rsplit(";", 2)[0] + "\n")
        done = run([sys.executable, BENCH / "quality_table.py", "--primary", old, "--diffuse", old, "--two-threads", old])
        self.assertNotEqual(done.returncode, 0)
        self.assertIn("no Quality column", done.stderr)


if __name__ == "__main__":
    unittest.main(verbosity=2)
