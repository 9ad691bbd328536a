#!/usr/bin/python3
"""Tests of examples/render/rmse_vs_time.py (against tests/fake_kdrt_render.py, which has kdrt-render's
command line) and examples/render/frames_to_video.sh (on frames ffmpeg makes, when ffmpeg is installed).

usage: tests/check_tools.py [RmseVsTime | FramesToVideo]   (unittest names; default: both)
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


if __name__ == "__main__":
    unittest.main(verbosity=2)
