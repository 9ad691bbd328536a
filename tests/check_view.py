#!/usr/bin/python3
"""kdrt-view's tests (tests/CMakeLists.txt registers one ctest test per check below).

usage: check_view.py CHECK KDRT_VIEW KDRT_RENDER WORKDIR

The viewer runs without a person (--frames, --keys, --screenshot) under SDL's offscreen driver or
Xvfb, as ctest's command line for each check sets up; x11_window drives a real X11 window with
xdotool. Screenshots are read by the PNG reader below (signature, chunk CRCs, zlib, the five
filters), not by the programs under test. Only the standard library: Debian's /usr/bin/python3.
"""
import ctypes
import os
import signal
import struct
import subprocess
import sys
import time
import zlib

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


class Failure(Exception):
    pass


def check(condition, message):
    if not condition:
        raise Failure(message)


def read_png(path):
    """(width, height, rows of RGB bytes, {tEXt keyword: text}) of an 8-bit RGB PNG, every chunk's
    CRC checked."""
    with open(path, "rb") as f:
        data = f.read()
    check(data[:8] == PNG_SIGNATURE, f"{path}: no PNG signature")
    pos, idat, text, header = 8, b"", {}, None
    while pos < len(data):
        check(pos + 8 <= len(data), f"{path}: truncated chunk header")
        length, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + length]
        (crc,) = struct.unpack(">I", data[pos + 8 + length:pos + 12 + length])
        check(zlib.crc32(kind + body) == crc, f"{path}: bad CRC in chunk {kind!r}")
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat += body
        elif kind == b"tEXt":
            key, _, value = body.partition(b"\0")
            text[key.decode("latin-1")] = value.decode("latin-1")
        elif kind == b"IEND":
            break
        pos += 12 + length
    check(header is not None, f"{path}: no IHDR")
    width, height, depth, colour, _, _, interlace = header
    check((depth, colour, interlace) == (8, 2, 0), f"{path}: not 8-bit RGB, non-interlaced: {header}")
    raw = zlib.decompress(idat)
    stride = width * 3
    check(len(raw) == height * (stride + 1), f"{path}: {len(raw)} bytes of pixels for {width}x{height}")
    rows, previous = [], bytearray(stride)
    for y in range(height):
        kind, line = raw[y * (stride + 1)], bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for i in range(stride):
            a = line[i - 3] if i >= 3 else 0
            b = previous[i]
            c = previous[i - 3] if i >= 3 else 0
            if kind == 1:
                line[i] = (line[i] + a) & 255
            elif kind == 2:
                line[i] = (line[i] + b) & 255
            elif kind == 3:
                line[i] = (line[i] + (a + b) // 2) & 255
            elif kind == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[i] = (line[i] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
            else:
                check(kind == 0, f"{path}: unknown filter {kind}")
        rows.append(bytes(line))
        previous = line
    return width, height, rows, text


def run(command, expect_status=0, env=None, timeout=60):
    """Runs command; returns its standard error and output together. Fails on another status."""
    full_env = dict(os.environ)
    full_env.update(env or {})
    p = subprocess.run(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, env=full_env, timeout=timeout)
    out = p.stdout.decode("utf-8", "replace")
    print("$ " + " ".join(command) + f"  -> {p.returncode}\n" + out, end="" if out.endswith("\n") else "\n")
    check(p.returncode == expect_status, f"exit status {p.returncode}, expected {expect_status}")
    return out


def view_shot(ctx, name, *args):
    path = os.path.join(ctx.work, name)
    run([ctx.view, *args, "--screenshot", path])
    return read_png(path)


def render_png(ctx, name, *args):
    path = os.path.join(ctx.work, name)
    run([ctx.render, *args, "-o", path])
    return read_png(path)


def differing_pixels(a, b):
    check(a[:2] == b[:2], f"sizes differ: {a[:2]} and {b[:2]}")
    count = 0
    for ra, rb in zip(a[2], b[2]):
        for x in range(0, len(ra), 3):
            count += ra[x:x + 3] != rb[x:x + 3]
    return count


# ---- the checks ----

def check_matches_render(ctx):
    """After n frames the screenshot is kdrt-render's PNG at NSAMPLES = n, same size and seed:
    exactly (tolerance 0 in every 8-bit channel), for 1 frame (the pixels' centres), 2 (the restart
    on two jittered samples) and 3; soft shadows, glass and a mesh."""
    for preset, frames in (("PHASE_2_SOFT_SHADOWS", 3), ("PHASE_4_REFRACTION", 2), ("PICTURE", 1), ("PICTURE", 3)):
        shot = view_shot(ctx, f"view-{preset}-{frames}.png", "--preset", preset, "--size", "64x48", "--seed", "7",
                         "--frames", str(frames))
        ref = render_png(ctx, f"render-{preset}-{frames}.png", "--preset", preset, "--size", "64x48", "--seed", "7",
                         "--set", f"NSAMPLES={frames}")
        check(shot[3].get("Title") == preset, f"the screenshot names {shot[3].get('Title')!r}, not {preset}")
        check(shot[3].get("Comment", "").startswith(f"{frames} sample"), f"Comment {shot[3].get('Comment')!r}")
        differ = differing_pixels(shot, ref)
        check(differ == 0, f"{preset}, {frames} frames: {differ} pixels differ from kdrt-render's")
    # stb_image (through kdrt-render's --reference) decodes the screenshot as well: 8-bit sRGB
    # against the same render's linear floats, so the RMSE is the rounding's and the clamping's
    # to [0, 1] (0.006 here; an image misread, or another one, is ten times that or more).
    out = run([ctx.render, "--preset", "PICTURE", "--size", "64x48", "--seed", "7", "--set", "NSAMPLES=3",
               "--reference", os.path.join(ctx.work, "view-PICTURE-3.png"), "-o", os.path.join(ctx.work, "again.png")])
    rmse = [float(l[5:]) for l in out.splitlines() if l.startswith("rmse=")]
    check(rmse and rmse[0] < 0.02, f"stb_image's reading of the screenshot: {rmse}")


def check_preset_key(ctx):
    """p moves to the next preset in kdrt-render --list-presets' order, P to the one before,
    wrapping around; the screenshot changes and names the new one. From a --scene file, p goes to
    the first preset and P to the last."""
    presets = run([ctx.render, "--list-presets"]).split()
    base = view_shot(ctx, "picture.png", "--preset", "PICTURE", "--size", "64x48", "--frames", "1")
    nxt = view_shot(ctx, "p.png", "--preset", "PICTURE", "--size", "64x48", "--frames", "1", "--keys", "p")
    check(nxt[3].get("Title") == presets[presets.index("PICTURE") + 1], f"p gave {nxt[3].get('Title')!r}")
    check(differing_pixels(base, nxt) > 100, "p did not change the image")
    back = view_shot(ctx, "pp.png", "--preset", "PHASE_1", "--size", "64x48", "--frames", "1", "--keys", "P,P,p")
    check(back[3].get("Title") == presets[-1], f"P,P,p from PHASE_1 gave {back[3].get('Title')!r}")
    # A scene file opens as kdrt-render reads it; p leaves it for the first preset, P for the last.
    scene = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "examples", "render", "scenes", "cornell.yaml")
    shot = view_shot(ctx, "scene.png", "--scene", scene, "--size", "64x48", "--frames", "1")
    check(shot[3].get("Title", "").endswith("cornell.yaml"), f"the scene file's screenshot names {shot[3].get('Title')!r}")
    for key, preset in (("p", presets[0]), ("P", presets[-1])):
        shot = view_shot(ctx, f"scene-{key}.png", "--scene", scene, "--size", "64x48", "--frames", "1", "--keys", key)
        check(shot[3].get("Title") == preset, f"{key} from a scene file gave {shot[3].get('Title')!r}")


def check_boxes_key(ctx):
    """k draws the kd-tree's boxes over the image, ] deeper ones, and k again takes them off."""
    args = ["--preset", "BENCHMARKS", "--size", "96x72"]
    # k does not start the image again: a frame before each key, then one, so compare with as
    # many frames without keys.
    plain2 = view_shot(ctx, "plain2.png", *args, "--frames", "2")
    plain3 = view_shot(ctx, "plain3.png", *args, "--frames", "3")
    boxes = view_shot(ctx, "boxes.png", *args, "--frames", "1", "--keys", "k")
    deeper = view_shot(ctx, "deeper.png", *args, "--frames", "1", "--keys", "],],k")
    off = view_shot(ctx, "off.png", *args, "--frames", "1", "--keys", "k,k")
    check(differing_pixels(plain2, boxes) > 50, "k drew no boxes")
    check(differing_pixels(plain2, boxes) < differing_pixels(plain3, deeper), "] drew no deeper boxes")
    check(differing_pixels(plain3, off) == 0, "k twice did not restore the image")


def check_rebuild_keys(ctx):
    """+ and - rebuild the tree at the next max leaf size, b with the other builder; each build
    is printed with its time."""
    args = ["--preset", "BENCHMARKS", "--size", "32x24", "--frames", "1"]
    out = run([ctx.view, *args, "--keys", "+,+,-,b"])
    for line in ("(SAH, max leaf size 4,", "(SAH, max leaf size 5,", "(SAH, max leaf size 6,", "(median, max leaf size 5,"):
        check("tree built in " in out and line in out, f"no build line with '{line}'")
    check(out.count("tree built in") == 5, "not one build line per build")
    # - stops at 1 (no rebuild), + stops at 64.
    out = run([ctx.view, *args, "--set", "MAX_LEAF_SIZE=1", "--keys", "-,+"])
    check(out.count("tree built in") == 2 and "(SAH, max leaf size 2," in out, "- below 1 rebuilt, or + did not")
    out = run([ctx.view, *args, "--set", "MAX_LEAF_SIZE=64", "--keys", "+"])
    check(out.count("tree built in") == 1, "+ above 64 rebuilt")


def check_settings_keys(ctx):
    """g, m, s and i change the image and restart it (the sample count starts again)."""
    args = ["--preset", "PICTURE", "--size", "64x48", "--frames", "2"]
    base = view_shot(ctx, "base.png", *args)
    for key in ("g", "m", "s", "i"):
        shot = view_shot(ctx, f"key-{key}.png", *args, "--keys", key)
        check(shot[3].get("Comment", "").startswith("2 samples"), f"{key}: {shot[3].get('Comment')!r}")
        check(differing_pixels(base, shot) > 0, f"{key} did not change PICTURE")


def check_orbit_preview(ctx):
    """--orbit turns the camera every frame as a drag does: each such frame is a preview at half
    the width and height (image=32x24 in --stats for a 64x48 window), unless --no-preview; the
    view changes."""
    args = ["--preset", "PHASE_2_HARD_SHADOWS", "--size", "64x48", "--frames", "2", "--stats"]
    out = run([ctx.view, *args, "--orbit", "20", "--screenshot", os.path.join(ctx.work, "orbit.png")])
    check("frames=2 size=64x48 image=32x24 " in out, "--orbit did not preview at half size")
    out = run([ctx.view, *args, "--orbit", "20", "--no-preview", "--screenshot", os.path.join(ctx.work, "full.png")])
    check("frames=2 size=64x48 image=64x48 " in out, "--no-preview still previewed")
    still = view_shot(ctx, "still.png", *args)
    check(differing_pixels(still, read_png(os.path.join(ctx.work, "full.png"))) > 100, "--orbit did not turn the view")
    check(read_png(os.path.join(ctx.work, "orbit.png"))[:2] == (64, 48), "the preview's screenshot is not window-sized")


def check_bad_input(ctx):
    """Bad command lines exit 2, bad files and unwritable screenshots 1, each with one line. An
    unwritable screenshot (a folder of that name, a read-only file, a folder no file can be created
    in, a missing folder) is refused before the first frame (here 100,000 frames of PICTURE that
    would take many minutes), and the line names the user's path, never a temporary."""
    scene = os.path.join(ctx.work, "bad.yaml")
    with open(scene, "w") as f:
        f.write("camera: [1, 2\n")
    folder = os.path.join(ctx.work, "taken.png")
    os.makedirs(folder, exist_ok=True)
    locked = os.path.join(ctx.work, "locked.png")
    if os.path.exists(locked):
        os.chmod(locked, 0o644)
    with open(locked, "w") as f:
        f.write("the old file")
    os.chmod(locked, 0o444)
    missing = os.path.join(ctx.work, "no-such-folder", "x.png")
    slow = ["--preset", "PICTURE", "--frames", "100000", "--screenshot"]
    cases = [
        (["--preset", "PHASE_9"], 2, "unknown preset 'PHASE_9'"),
        (["--preset", ""], 2, "unknown preset '' (presets: PHASE_1, "),
        (["--scene", ""], 2, "--scene needs a file"),
        (["--scene", os.path.join(ctx.work, "missing.yaml")], 1, "missing.yaml"),
        (["--scene", scene], 1, "bad.yaml"),
        (["--set", "NSAMPLES=many"], 2, "setting NSAMPLES: 'many' is not an integer"),
        (["--size", "64"], 2, "bad --size '64'"),
        (["--frames", "1", "--keys", "p,x"], 2, "unknown key 'x'"),
        (["--keys", "p"], 2, "give --frames N"),
        (["--frames", "1", "--screenshot", "out.jpg"], 2, "must end in .png"),
        (["--bogus"], 2, "unknown argument '--bogus'"),
        ([*slow, folder], 1, f"cannot write '{folder}': it exists and is not a regular file"),
        ([*slow, locked], 1, f"cannot write '{locked}': it is read-only"),
        ([*slow, "/proc/kdrt-view-test.png"], 1, "cannot write '/proc/kdrt-view-test.png': cannot create a file in '/proc'"),
        ([*slow, missing], 1, f"cannot write '{missing}': the folder '{os.path.dirname(missing)}' does not exist"),
    ]
    for args, status, message in cases:
        out = run([ctx.view, *args], expect_status=status, timeout=30)
        lines = [l for l in out.splitlines() if l.startswith("kdrt-view: ") and message in l]
        check(lines, f"{args}: no line with '{message}'")
        check(".tmp-" not in out, f"{args}: a temporary named")
        check(not any("Sanitizer" in l for l in out.splitlines()), f"{args}: a sanitizer report")
    check(os.listdir(folder) == [], "the folder was changed")
    with open(locked) as f:
        check(f.read() == "the old file", "the read-only file was changed")
    os.chmod(locked, 0o644)
    check(not [n for n in os.listdir(ctx.work) if ".tmp-" in n], "a temporary was left")


def check_interrupted(ctx):
    """SIGINT or SIGTERM while --frames N --screenshot OUT renders: it dies of that signal (130
    or 143 in a shell, as kdrt-render does), and OUT is the old file, with no temporary left."""
    def default_signals():  # as in a terminal, whatever ctest's own dispositions are
        signal.signal(signal.SIGINT, signal.SIG_DFL)
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
    for sig in (signal.SIGINT, signal.SIGTERM):
        shot = os.path.join(ctx.work, f"old-{sig.name}.png")
        with open(shot, "w") as f:
            f.write("the old file")
        log = open(os.path.join(ctx.work, f"{sig.name}.log"), "w+")
        proc = subprocess.Popen([ctx.view, "--preset", "PICTURE", "--size", "160x120", "--frames", "1000000",
                                 "--screenshot", shot], stdout=log, stderr=subprocess.STDOUT, preexec_fn=default_signals)
        try:
            def log_text():
                log.flush()
                log.seek(0)
                return log.read()
            wait_for(lambda: "tree built in" in log_text() or proc.poll() is not None, "the tree to be built")
            time.sleep(1)  # frames rendering
            check(proc.poll() is None, f"it ended before the signal, status {proc.returncode}")
            proc.send_signal(sig)
            status = proc.wait(timeout=30)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        print(f"$ kdrt-view ... --screenshot {shot}, sent {sig.name} -> {status}\n{log_text()}")
        check(status == -sig, f"exit status {status}, not death by {sig.name}")
        with open(shot) as f:
            check(f.read() == "the old file", f"{shot} was changed")
        check(not [n for n in os.listdir(ctx.work) if ".tmp-" in n], "a temporary was left")


def check_names_any_case(ctx):
    """Names ignore case: presets and settings, and keys of more than one letter (a letter's case
    is shift: p and P are two keys)."""
    shot = view_shot(ctx, "cases.png", "--preset", "phase_2_hard_shadows", "--set", "nsamples=1", "--size", "32x24",
                     "--frames", "1", "--keys", "pageup,LEFT,esc")
    check(shot[3].get("Title") == "PHASE_2_HARD_SHADOWS", f"the screenshot names {shot[3].get('Title')!r}")


def check_mesh_dir_env(ctx):
    """The environment's KDRT_MESH_DIR, when set, is the mesh folder instead of the one configured
    at build time; --help says both."""
    none = os.path.join(ctx.work, "no-meshes")
    out = run([ctx.view, "--preset", "PHASE_3_INTERPOLATION", "--size", "16x12", "--frames", "1"],
              env={"KDRT_MESH_DIR": none})
    check(f"generated torus (no mesh folder {none} for stanford-bunny)" in out, "the environment's folder was not used")
    help_text = run([ctx.view, "--help"])
    check("$KDRT_MESH_DIR, else the one configured at build time: " in help_text, "--help does not say both")


def check_no_display(ctx):
    """No display: one clear line (nothing else: the window is opened before the scene is loaded)
    and exit status 1, not SDL's invisible offscreen window."""
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY", "SDL_VIDEODRIVER")}
    for extra in ({}, {"DISPLAY": ":9999"}):
        e = dict(env)
        e.update(extra)
        p = subprocess.run([ctx.view, "--preset", "PHASE_1", "--frames", "1"], stdout=subprocess.PIPE,
                           stderr=subprocess.STDOUT, env=e, timeout=60)
        out = p.stdout.decode("utf-8", "replace")
        print(f"$ {extra} kdrt-view --preset PHASE_1 --frames 1 -> {p.returncode}\n{out}")
        check(p.returncode == 1, f"exit status {p.returncode} without a display")
        lines = [l for l in out.splitlines() if l.startswith("kdrt-view")]  # not LSan's suppression table
        check(len(lines) == 1 and lines[0].startswith("kdrt-view: cannot open a window: no display"),
              "not one 'no display' line")


def check_headless_x11(ctx):
    """Under Xvfb (a real X11 window, no person): renders, replays keys, and matches kdrt-render."""
    check(os.environ.get("DISPLAY"), "no DISPLAY: run under xvfb-run")
    shot = view_shot(ctx, "x11.png", "--preset", "PHASE_2_HARD_SHADOWS", "--size", "64x48", "--frames", "2",
                     "--seed", "3", "--keys", "p,P")
    ref = render_png(ctx, "x11-ref.png", "--preset", "PHASE_2_HARD_SHADOWS", "--size", "64x48", "--seed", "3",
                     "--set", "NSAMPLES=2")
    check(differing_pixels(shot, ref) == 0, "the X11 screenshot differs from kdrt-render's")


class XClientMessageEvent(ctypes.Structure):
    _fields_ = [("type", ctypes.c_int), ("serial", ctypes.c_ulong), ("send_event", ctypes.c_int),
                ("display", ctypes.c_void_p), ("window", ctypes.c_ulong), ("message_type", ctypes.c_ulong),
                ("format", ctypes.c_int), ("data", ctypes.c_long * 5)]


def close_window(window):
    """What a window manager's close button does: a WM_DELETE_WINDOW message, through libX11."""
    x11 = ctypes.CDLL("libX11.so.6")
    x11.XOpenDisplay.restype = ctypes.c_void_p
    x11.XOpenDisplay.argtypes = [ctypes.c_char_p]
    x11.XInternAtom.restype = ctypes.c_ulong
    x11.XInternAtom.argtypes = [ctypes.c_void_p, ctypes.c_char_p, ctypes.c_int]
    x11.XSendEvent.argtypes = [ctypes.c_void_p, ctypes.c_ulong, ctypes.c_int, ctypes.c_long, ctypes.c_void_p]
    x11.XFlush.argtypes = [ctypes.c_void_p]
    x11.XCloseDisplay.argtypes = [ctypes.c_void_p]
    display = x11.XOpenDisplay(None)
    check(display, "cannot open the X display")
    event = (ctypes.c_char * 192)()  # XEvent is a union of 24 longs
    message = XClientMessageEvent.from_buffer(event)
    message.type = 33  # ClientMessage
    message.window = window
    message.message_type = x11.XInternAtom(display, b"WM_PROTOCOLS", 0)
    message.format = 32
    message.data[0] = x11.XInternAtom(display, b"WM_DELETE_WINDOW", 0)
    message.data[1] = 0  # CurrentTime
    x11.XSendEvent(display, window, 0, 0, ctypes.byref(event))
    x11.XFlush(display)
    x11.XCloseDisplay(display)


def wait_for(predicate, what, seconds=30):
    end = time.time() + seconds
    while time.time() < end:
        if predicate():
            return
        time.sleep(0.05)
    raise Failure(f"timed out waiting for {what}")


def check_x11_window(ctx):
    """A person's session, under Xvfb: the interactive viewer's real X11 window gets key events
    from xdotool (XTEST): p, F12 (a screenshot of the new preset), a resize, F12 again at the new
    size; then its window is closed as a window manager closes it, and it exits with status 0 (no
    leak under ASan). A second run quits on Esc."""
    check(os.environ.get("DISPLAY"), "no DISPLAY: run under xvfb-run")
    shot = os.path.join(ctx.work, "window.png")
    log = open(os.path.join(ctx.work, "window.log"), "w+")
    proc = subprocess.Popen([ctx.view, "--preset", "PHASE_1", "--size", "96x72", "--screenshot", shot],
                            stdout=log, stderr=subprocess.STDOUT)
    try:
        out = subprocess.run(["xdotool", "search", "--sync", "--name", "^kdrt-view"], stdout=subprocess.PIPE,
                             timeout=30).stdout.split()
        check(out, "no kdrt-view window")
        window = out[0].decode()
        print(f"window {window}")
        subprocess.run(["xdotool", "windowfocus", "--sync", window], check=True, timeout=30)

        def log_text():
            log.flush()
            log.seek(0)
            return log.read()

        def shot_of(title, size):
            def done():
                if not os.path.exists(shot):
                    return False
                try:
                    w, h, _, text = read_png(shot)
                except Failure:
                    return False
                return text.get("Title") == title and (w, h) == size
            return done

        subprocess.run(["xdotool", "key", "p", "F12"], check=True, timeout=30)
        wait_for(shot_of("PHASE_2_NO_SHADOWS", (96, 72)), "a screenshot of PHASE_2_NO_SHADOWS after p, F12")
        before = read_png(shot)
        os.remove(shot)
        # A drag with the left button orbits the camera: the next screenshot shows another view.
        subprocess.run(["xdotool", "mousemove", "--window", window, "30", "36", "mousedown", "1", "mousemove",
                        "--window", window, "45", "36", "mousemove", "--window", window, "60", "36", "mouseup", "1",
                        "key", "F12"], check=True, timeout=30)
        wait_for(shot_of("PHASE_2_NO_SHADOWS", (96, 72)), "a screenshot after a drag")
        check(differing_pixels(before, read_png(shot)) > 100, "dragging with the mouse did not turn the camera")
        subprocess.run(["xdotool", "windowsize", window, "120", "90", "key", "P"], check=True, timeout=30)  # P: shift+p
        # F12 until the resize has reached the viewer (a screenshot of the new size).
        end = time.time() + 30
        while True:
            subprocess.run(["xdotool", "key", "F12"], check=True, timeout=30)
            try:
                wait_for(shot_of("PHASE_1", (120, 90)), "", seconds=1)
                break
            except Failure:
                check(time.time() < end, "no 120x90 screenshot of PHASE_1 after the resize and shift+p")
        close_window(int(window))
        status = proc.wait(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    print(log_text())
    check(status == 0, f"exit status {status} after the window was closed")

    proc = subprocess.Popen([ctx.view, "--preset", "PHASE_1", "--size", "64x48"], stdout=log,
                            stderr=subprocess.STDOUT)
    try:
        out = subprocess.run(["xdotool", "search", "--sync", "--name", "^kdrt-view"], stdout=subprocess.PIPE,
                             timeout=30).stdout.split()
        check(out, "no kdrt-view window the second time")
        subprocess.run(["xdotool", "windowfocus", "--sync", out[0].decode(), "key", "Escape"], check=True, timeout=30)
        status = proc.wait(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    check(status == 0, f"exit status {status} after Esc")


class Context:
    def __init__(self, view, render, work):
        self.view, self.render, self.work = view, render, work


def main():
    checks = {name[len("check_"):]: f for name, f in globals().items() if name.startswith("check_") and callable(f)}
    if len(sys.argv) != 5 or sys.argv[1] not in checks:
        print(__doc__ + "\nchecks: " + " ".join(sorted(checks)), file=sys.stderr)
        return 2
    work = os.path.join(sys.argv[4], sys.argv[1])
    os.makedirs(work, exist_ok=True)
    try:
        checks[sys.argv[1]](Context(sys.argv[2], sys.argv[3], work))
    except (Failure, subprocess.TimeoutExpired) as e:
        print(f"FAILED: {e}")
        return 1
    print("passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
