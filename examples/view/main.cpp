// kdrt-view: kdrt-render's presets and scene files in a window, ray traced on every core and
// refined frame after frame while the camera stands still; keys for the settings and the kd-tree.
// Without a person: --frames N --screenshot OUT.png, and --keys to replay keys.
#include "common/atomic_file.hpp"  // common::check_replaceable
#include "common/mesh_io.hpp"  // common::mesh_dir_help
#include "common/output.hpp"  // common::guarded_main, UsageError
#include "common/parse.hpp"   // common::parse_count
#include "common/timing.hpp"  // common::Stopwatch
#include "command_line.hpp"
#include "viewer.hpp"

#include <SDL.h>

#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <new>
#include <string>
#include <vector>

namespace {

const char *const kUsage =
    "usage: kdrt-view [--preset NAME | --scene FILE] [--set KEY=VALUE]... [--size WxH]\n"
    "                 [--threads N] [--seed N] [--frames N [--keys K1,K2,...]] [--orbit DEGREES]\n"
    "                 [--no-preview] [--screenshot OUT.png] [--stats]\n"
    "       kdrt-view --help\n"
    "\n"
    "Shows a preset of the original ray tracer (default PICTURE) or a YAML scene file in a window,\n"
    "ray traced on every core through kdrt-render's renderer: one sample a pixel while the camera\n"
    "moves, more every frame while it stands still (after n frames the image is kdrt-render's with\n"
    "NSAMPLES = n and the same seed, bit for bit; NSAMPLES itself is not used).\n"
    "\n"
    "  --preset NAME       one of kdrt-render --list-presets (in any case, as setting names and\n"
    "                      true and false are); p and P cycle them\n"
    "  --scene FILE        a YAML scene file (format: examples/render/scene_file.hpp)\n"
    "  --set KEY=VALUE     a setting, after each preset's or the file's own (repeatable; the names\n"
    "                      are kdrt-render's, see its --help)\n"
    "  --size WxH          the window's size (default 640x480; sides 1..16384, at most 64 Mpixels)\n"
    "  --threads N         render and build threads (default: every core)\n"
    "  --seed N            seed of the per-pixel random streams (default 0)\n"
    "  --frames N          no person: render N frames (after the --keys), write --screenshot, exit\n"
    "  --keys K1,K2,...    with --frames: press these keys, one after each frame, before the N\n"
    "                      frames: p P w a S d q e Up Down Left Right PageUp PageDown g m s i\n"
    "                      + - b k [ ] h F12 F2 Esc (S is shift+s: a letter's case matters, the\n"
    "                      longer names are taken in any case)\n"
    "  --orbit DEGREES     turn the camera about its target by DEGREES every frame, as a drag does,\n"
    "                      so every frame starts again at one sample a pixel (to measure the frame\n"
    "                      rate moving)\n"
    "  --no-preview        full size while the camera moves too (default: the frame after a move\n"
    "                      is rendered at half the width and height and shown doubled)\n"
    "  --screenshot OUT    the PNG F12 and F2 write (default kdrt-view-NNNN.png, the first free\n"
    "                      number), and --frames at the end; checked at the start (one that\n"
    "                      cannot be written is a failure before the first frame)\n"
    "  --stats             at exit, print the frames' milliseconds (median, mean) and MRays/s\n"
    "  --help              this text\n"
    "\n"
    "Keys: p / shift+p next / previous preset; mouse drag orbit, right or middle drag pan, wheel\n"
    "zoom; w a shift+s d (or the arrows) forward, left, back, right, q e (PageDown, PageUp) down,\n"
    "up; g glass, m mirrors, s shadows (0, hard, soft), i normal interpolation; + - the max leaf\n"
    "size (the tree rebuilt), b median / SAH builder; k the kd-tree's boxes, [ ] their depth;\n"
    "F12 or F2 a screenshot; h help; Esc quit. p and P load the preset's own settings again.\n"
    "\n"
    "Meshes are kdrt-render's, from the mesh folder:\n"
    "  MESH_DIR.\n"
    "Without a display it fails (set DISPLAY, or SDL_VIDEODRIVER=offscreen for no window at all).\n"
    "Exit status: 0 success, 1 failure (no display, unreadable scene, unwritable screenshot), 2 a\n"
    "bad command line, 128+N killed by signal N (130 SIGINT, 143 SIGTERM: no screenshot is then\n"
    "written, and an old file of that name is kept).\n";

using common::UsageError;

const double kPi = 3.14159265358979323846;

int fail(const std::string &message, int code)
{
    std::fprintf(stderr, "kdrt-view: %s\n", message.c_str());
    return code;
}

// The viewer's name for a key (view::key_names()), or "" for keys it does not use.
std::string key_name(const SDL_Keysym &k)
{
    switch (k.sym) {
    case SDLK_ESCAPE: return "Esc";
    case SDLK_F12: return "F12";
    case SDLK_F2: return "F2";
    case SDLK_PLUS: case SDLK_KP_PLUS: case SDLK_EQUALS: return "+";
    case SDLK_MINUS: case SDLK_KP_MINUS: return "-";
    case SDLK_LEFTBRACKET: return "[";
    case SDLK_RIGHTBRACKET: return "]";
    case SDLK_UP: return "Up";
    case SDLK_DOWN: return "Down";
    case SDLK_LEFT: return "Left";
    case SDLK_RIGHT: return "Right";
    case SDLK_PAGEUP: return "PageUp";
    case SDLK_PAGEDOWN: return "PageDown";
    default: break;
    }
    if (k.sym >= SDLK_a && k.sym <= SDLK_z) {
        const char c = char('a' + (k.sym - SDLK_a));
        const std::string name(1, (k.mod & KMOD_SHIFT) ? char(c - 'a' + 'A') : c);
        for (const std::string &known : view::key_names())
            if (known == name) return name;
    }
    return "";
}

// kdrt-view-0001.png, the first that does not exist.
std::string next_screenshot_name()
{
    for (unsigned n = 1;; ++n) {
        char name[32];
        std::snprintf(name, sizeof name, "kdrt-view-%04u.png", n);
        if (access(name, F_OK) != 0) return name;
    }
}

// The window, its renderer and the texture the frames go to; everything freed in reverse order.
struct Window {
    SDL_Window *window = nullptr;
    SDL_Renderer *renderer = nullptr;
    SDL_Texture *texture = nullptr;
    int texture_w = 0, texture_h = 0;
    bool sdl = false;

    ~Window()
    {
        if (texture) SDL_DestroyTexture(texture);
        if (renderer) SDL_DestroyRenderer(renderer);
        if (window) SDL_DestroyWindow(window);
        if (sdl) SDL_Quit();
    }

    bool open(uint32_t width, uint32_t height, std::string &error)
    {
        // Without SDL_VIDEODRIVER, SDL tries every driver and ends on its offscreen one, a window
        // no one sees: so only X11 (DISPLAY) or Wayland (WAYLAND_DISPLAY) here, and the offscreen
        // or dummy driver only when SDL_VIDEODRIVER asks for it.
        const char *asked = std::getenv("SDL_VIDEODRIVER");
        std::vector<std::string> drivers;
        if (asked && *asked) drivers.push_back(asked);
        else {
            if (std::getenv("DISPLAY")) drivers.push_back("x11");
            if (std::getenv("WAYLAND_DISPLAY")) drivers.push_back("wayland");
        }
        SDL_SetHint(SDL_HINT_FRAMEBUFFER_ACCELERATION, "0");
        // SDL would turn SIGINT and SIGTERM into SDL_QUIT, a normal end that writes the
        // --screenshot of fewer frames than asked over the old file. Without its handlers they
        // end the process as they end kdrt-render (a screenshot being written then leaves no
        // temporary: common::write_atomically).
        SDL_SetHint(SDL_HINT_NO_SIGNAL_HANDLERS, "1");
        SDL_SetHint(SDL_HINT_RENDER_DRIVER, "software");
        std::string why = "DISPLAY is not set";
        for (const std::string &driver : drivers) {
            if (!(asked && *asked)) SDL_SetHint(SDL_HINT_VIDEODRIVER, driver.c_str());
            if (SDL_Init(SDL_INIT_VIDEO) == 0) {
                sdl = true;
                break;
            }
            why = SDL_GetError();
            SDL_Quit();
        }
        if (!sdl) {
            error = "cannot open a window: no display (" + why +
                    "; set DISPLAY to an X server, or SDL_VIDEODRIVER=offscreen to render without a window)";
            return false;
        }
        window = SDL_CreateWindow("kdrt-view", SDL_WINDOWPOS_UNDEFINED, SDL_WINDOWPOS_UNDEFINED, int(width), int(height),
                                  SDL_WINDOW_RESIZABLE);
        if (!window) {
            error = std::string("cannot open a window: ") + SDL_GetError();
            return false;
        }
        // The frames are made on the CPU: SDL's software renderer copies them to the window, and
        // no OpenGL driver is loaded.
        renderer = SDL_CreateRenderer(window, -1, SDL_RENDERER_SOFTWARE);
        if (!renderer) {
            error = std::string("cannot draw in the window: ") + SDL_GetError();
            return false;
        }
        return true;
    }

    // The size frames are rendered at: the window's drawable size.
    void size(uint32_t &width, uint32_t &height) const
    {
        int w = 0, h = 0;
        if (SDL_GetRendererOutputSize(renderer, &w, &h) != 0 || w <= 0 || h <= 0) SDL_GetWindowSize(window, &w, &h);
        width = uint32_t(std::max(1, w)), height = uint32_t(std::max(1, h));
    }

    bool show(const std::vector<uint32_t> &pixels, uint32_t width, uint32_t height, std::string &error)
    {
        if (!texture || texture_w != int(width) || texture_h != int(height)) {
            if (texture) SDL_DestroyTexture(texture);
            texture = SDL_CreateTexture(renderer, SDL_PIXELFORMAT_ARGB8888, SDL_TEXTUREACCESS_STREAMING, int(width),
                                        int(height));
            if (!texture) {
                error = std::string("cannot make the window's texture: ") + SDL_GetError();
                return false;
            }
            texture_w = int(width), texture_h = int(height);
        }
        if (SDL_UpdateTexture(texture, nullptr, pixels.data(), int(width * 4)) != 0 ||
            SDL_RenderClear(renderer) != 0 || SDL_RenderCopy(renderer, texture, nullptr, nullptr) != 0) {
            error = std::string("cannot draw in the window: ") + SDL_GetError();
            return false;
        }
        SDL_RenderPresent(renderer);
        return true;
    }
};

double median(std::vector<double> v)
{
    if (v.empty()) return 0;
    std::sort(v.begin(), v.end());
    return v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
}

int run(int argc, char **argv)
{
    kr::SceneArgs args;
    args.width = 640, args.height = 480;
    uint64_t frames = 0;
    double orbit_degrees = 0;
    std::string screenshot, keys_text;
    bool stats = false, have_keys = false, no_preview = false;

    for (int i = 1; i < argc; ++i) {
        const std::string arg = argv[i];
        auto value = [&]() -> std::string {
            if (i + 1 >= argc) throw UsageError{arg + " needs a value (see --help)"};
            return argv[++i];
        };
        if (kr::take_scene_arg(arg, value, args)) continue;
        if (arg == "--help" || arg == "-h") {
            std::string usage = kUsage;
            usage.replace(usage.find("MESH_DIR."), 8, common::mesh_dir_help());
            std::fputs(usage.c_str(), stdout);
            return 0;
        } else if (arg == "--frames") {
            const std::string v = value();
            if (!common::parse_count(v, 1000000, frames) || frames == 0) throw UsageError{"bad --frames '" + v + "': expected 1..1000000"};
        } else if (arg == "--keys") {
            keys_text = value();
            have_keys = true;
        } else if (arg == "--orbit") {
            const std::string v = value();
            char *end = nullptr;
            orbit_degrees = std::strtod(v.c_str(), &end);
            if (v.empty() || *end != '\0' || !std::isfinite(orbit_degrees) || std::fabs(orbit_degrees) > 360)
                throw UsageError{"bad --orbit '" + v + "': expected degrees, -360..360"};
        } else if (arg == "--screenshot") {
            screenshot = value();
        } else if (arg == "--stats") {
            stats = true;
        } else if (arg == "--no-preview") {
            no_preview = true;
        } else {
            throw UsageError{"unknown argument '" + arg + "' (see --help)"};
        }
    }
    if (!args.preset.empty() && !args.scene_file.empty()) throw UsageError{"give --preset or --scene, not both"};
    view::Options options;
    options.preset = args.preset, options.scene_file = args.scene_file, options.sets = args.sets;
    options.threads = args.threads, options.seed = args.seed;
    const uint32_t width = args.width, height = args.height;
    if (have_keys && frames == 0) throw UsageError{"--keys replays keys for --frames: give --frames N"};
    if (!screenshot.empty()) {
        const size_t dot = screenshot.find_last_of('.'), slash = screenshot.find_last_of('/');
        std::string ext = dot == std::string::npos || (slash != std::string::npos && dot < slash) ? "" : screenshot.substr(dot);
        for (char &c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
        if (ext != ".png") throw UsageError{"bad --screenshot '" + screenshot + "': it must end in .png"};
    }
    std::vector<std::string> keys;
    if (have_keys) {
        size_t start = 0;
        for (;;) {
            const size_t comma = keys_text.find(',', start);
            std::string k = keys_text.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
            const std::vector<std::string> &names = view::key_names();
            if (k.size() > 1)  // a name (Esc, PageUp, F12) in any case; a letter's case is shift
                for (const std::string &n : names)
                    if (n.size() == k.size() && std::equal(n.begin(), n.end(), k.begin(), [](char a, char b) {
                            return std::tolower(static_cast<unsigned char>(a)) == std::tolower(static_cast<unsigned char>(b));
                        }))
                        k = n;
            if (std::find(names.begin(), names.end(), k) == names.end()) {
                std::string list;
                for (const std::string &n : names) list += " " + n;
                throw UsageError{"bad --keys: unknown key '" + k + "' (keys:" + list + ")"};
            }
            keys.push_back(k);
            if (comma == std::string::npos) break;
            start = comma + 1;
        }
    }

    // An unknown preset is a bad command line, display or not; then the window, so that without a
    // display that is all there is to say; then the scene (its meshes may take a while).
    std::string error;
    kr::Scene probe;
    if (options.scene_file.empty() && !options.preset.empty() && !kr::make_preset(options.preset, probe, error))
        throw UsageError{error};
    // A screenshot that cannot be written fails now, not after the frames.
    if (!screenshot.empty() && !common::check_replaceable(screenshot, error)) return fail(error, 1);
    Window window;
    if (!window.open(width, height, error)) return fail(error, 1);
    view::Viewer viewer(options);
    bool usage_error = false;
    if (!viewer.open(error, usage_error)) {
        if (usage_error) throw UsageError{error};
        return fail(error, 1);
    }

    std::vector<double> frame_ms, render_ms;
    uint64_t rays = 0;
    double render_total_ms = 0;
    const bool headless = frames != 0;
    const uint64_t total_frames = keys.size() + frames;  // a frame before each key, then N
    uint64_t frame = 0;
    size_t next_key = 0;
    bool quit = false, left = false, right = false, moved = false;
    int status = 0;
    const std::vector<std::string> move_keys = {"w", "a", "S", "d", "q", "e", "Up", "Down", "Left", "Right",
                                                "PageUp", "PageDown"};
    auto press = [&](const std::string &name) {
        if (std::find(move_keys.begin(), move_keys.end(), name) != move_keys.end()) moved = true;
        view::Viewer::KeyResult result;
        if (!viewer.key(name, result, error)) {
            std::fprintf(stderr, "kdrt-view: %s\n", error.c_str());
            return;
        }
        if (result == view::Viewer::KeyResult::quit) quit = true;
        if (result == view::Viewer::KeyResult::screenshot) {
            const std::string path = screenshot.empty() ? next_screenshot_name() : screenshot;
            if (!viewer.screenshot(path, error)) std::fprintf(stderr, "kdrt-view: %s\n", error.c_str()), status = 1;
        }
    };

    while (!quit && (!headless || frame < total_frames)) {
        // Events: all that are waiting, or, with nothing to render, the next one.
        SDL_Event e;
        bool have = viewer.converged() && !headless ? SDL_WaitEventTimeout(&e, 250) != 0 : SDL_PollEvent(&e) != 0;
        for (; have; have = SDL_PollEvent(&e) != 0) {
            if (e.type == SDL_QUIT) quit = true;
            else if (e.type == SDL_KEYDOWN) {
                const std::string name = key_name(e.key.keysym);
                if (!name.empty()) press(name);
            } else if (e.type == SDL_MOUSEBUTTONDOWN || e.type == SDL_MOUSEBUTTONUP) {
                const bool down = e.type == SDL_MOUSEBUTTONDOWN;
                if (e.button.button == SDL_BUTTON_LEFT) left = down;
                if (e.button.button == SDL_BUTTON_RIGHT || e.button.button == SDL_BUTTON_MIDDLE) right = down;  // pan
            } else if (e.type == SDL_MOUSEMOTION && (left || right)) {
                uint32_t w, h;
                window.size(w, h);
                if (left) viewer.orbit(e.motion.xrel, e.motion.yrel);
                else viewer.pan(e.motion.xrel, e.motion.yrel, h);
                moved = true;
            } else if (e.type == SDL_MOUSEWHEEL) {
                viewer.zoom(e.wheel.y);
                moved = true;
            }
        }
        if (quit) break;

        const common::Stopwatch clock;
        uint32_t w, h;
        window.size(w, h);
        if (orbit_degrees != 0) {
            viewer.orbit(orbit_degrees * kPi / 180 / 0.01, 0);  // orbit() turns 0.01 radians a pixel
            moved = true;
        }
        // The frame after the camera moved is a preview (half size), unless --no-preview.
        const bool preview = moved && !no_preview;
        moved = false;
        const bool rendering = preview || !viewer.converged() || w != viewer.width() || h != viewer.height();
        if (!viewer.render(w, h, preview, error)) return fail(error, 1);
        if (!window.show(viewer.compose(), viewer.width(), viewer.height(), error)) return fail(error, 1);
        if (rendering) {
            SDL_SetWindowTitle(window.window, viewer.status().c_str());
            frame_ms.push_back(clock.ms());
            render_ms.push_back(viewer.render_ms());
            render_total_ms += viewer.render_ms();
            rays += viewer.rays();
        }
        ++frame;
        if (headless && next_key < keys.size()) press(keys[next_key++]);
    }

    if (headless && !screenshot.empty() && !viewer.screenshot(screenshot, error)) return fail(error, 1);
    if (stats) {
        double sum = 0;
        for (double ms : frame_ms) sum += ms;
        const size_t n = frame_ms.size();
        // One line of KEY=VALUE: the frames rendered, the last one's window and image sizes, the
        // frames' wall time (rendering, overlay, the copy to the window) and accumulate()'s alone.
        std::printf("frames=%zu size=%ux%u image=%ux%u threads=%u frame_ms_median=%.2f frame_ms_mean=%.2f "
                    "render_ms_median=%.2f fps=%.2f mrays_per_s=%.2f\n",
                    n, viewer.width(), viewer.height(), viewer.image_width(), viewer.image_height(),
                    options.threads ? options.threads : common::all_cores(), median(frame_ms), n ? sum / double(n) : 0.0,
                    median(render_ms), sum > 0 ? 1000.0 * double(n) / sum : 0.0,
                    render_total_ms > 0 ? double(rays) / (render_total_ms * 1000) : 0.0);
    }
    return status;
}

}  // namespace

int main(int argc, char **argv)
{
    return common::guarded_main("kdrt-view", [&] { return run(argc, argv); });
}
