// The web viewer's program: libstipple's engine, plugins, render graph and shaders on the
// browser's WebGPU (a thin front end, as app/ is for the command line). The scene is assembled
// by libstipple's scene module as `stipple render` assembles it (scene::plan_scene: the same
// plugins, renderer choice, framing, point size and streaming): the built-in scene, a LAS/LAZ
// file, or a 3D Tiles tileset, COPC, Potree or EPT source by URL (--url), streamed frame by frame
// with the camera, one engine frame per animation frame. It is built as a factory (an ES module,
// -sEXPORT_ES6): web/stipple.mjs makes one instance per viewer, hands it its arguments and the
// canvas's selector (--canvas), and talks to it through slots of the instance's Module object
// (Module.stipple*), which the program polls once per animation frame. What is the page's own
// stays here: it draws straight into its WebGPU canvas (CanvasTargetPlugin: no readback), whose
// drawing buffer follows the size the module asks for (its container and devicePixelRatio), and
// reports what it does (Module.stippleReport: done, error, tile problems, stats, camera, the
// options it draws with); once drawn, the camera follows the module's pointer, wheel and key
// input, camera sets (viewer.camera, in the data's coordinates) and option changes
// (viewer.setOptions: `stipple render`'s options of the same names, changed while the view
// runs), and a source the module asks for (viewer.open: a URL, or a file in the instance's file
// system) is opened next. Frames are paced by the page's animation frames and drawn only when
// something changed (the camera, an option, the canvas's size, a tile arrived): an idle page
// draws nothing, and the canvas keeps showing the last frame. viewer.destroy() ends main at its
// next animation frame (Module.stippleQuit), and with it the instance's threads.
#include <emscripten.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "stipple/core/error.hpp"
#include "stipple/core/log.hpp"
#include "stipple/engine/engine.hpp"
#include "stipple/engine/plugins.hpp"
#include "stipple/engine/render_plugins.hpp"
#include "stipple/engine/viewport.hpp"
#include "stipple/io/fetch.hpp"
#include "stipple/math/camera.hpp"
#include "stipple/pointcloud/compute_raster.hpp"
#include "stipple/pointcloud/point_cloud.hpp"
#include "stipple/pointcloud/point_renderer.hpp"
#include "stipple/pointcloud/scene.hpp"
#include "stipple/scene/scene.hpp"
#include "stipple/splats/splat_plugin.hpp"
#include "stipple/tiles3d/splat_stream.hpp"
#include "stipple/tiles3d/streamer.hpp"
#include "stipple/tiles3d/tileset_plugin.hpp"
#include "stipple/tools/tools.hpp"

#include "canvas_target.hpp"
#include "tools_bridge.hpp"

// Resolves at the page's next animation frame (or after 100 ms where the page is hidden and
// frames are not run): the main thread's stack is suspended meanwhile (JSPI), so the page draws,
// and the streamer's requests finish on their workers.
// clang-format off
EM_ASYNC_JS(void, stipple_next_frame, (), {
  await new Promise((resolve) => {
    requestAnimationFrame(resolve);
    setTimeout(resolve, 100);
  });
});
// clang-format on

namespace {

using namespace stipple;

// Thrown at an animation frame once the module asked the program to end (viewer.destroy()):
// unwinds the view (the engine shuts down) up to main, which exits. Not a std::exception, so
// that no error handler takes it for one.
struct Quit {};

// Waits for the page's next animation frame; throws Quit once the module asked the program to
// end.
void next_frame() {
  stipple_next_frame();
  if (EM_ASM_INT({ return Module.stippleQuit ? 1 : 0; })) throw Quit{};
}

struct Options {
  // Inputs, the built-in scene, the points' look (colour mode, EDL and point size, 0: from the
  // data's density), the point budget and the streaming budgets, as `stipple render`'s options
  // of the same names.
  scene::SceneOptions scene;
  // The canvas's first size (the module's: its container's in device pixels, or ?width=&height=)
  // and the camera (`stipple render --camera`; else framed from the default azimuth and
  // elevation).
  scene::SceneView view;
  // URLs to open (the page's ?url=, repeated for several clouds at once): a LAS/LAZ file is
  // fetched into the page's memory and read whole (several are drawn together, as `stipple render
  // a.laz b.laz`); anything else (tileset.json, COPC, Potree, EPT) is streamed, one at a time.
  std::vector<std::string> urls;
  std::string canvas = "#canvas";  // the canvas's selector (the module gives each its own id)
  uint64_t frames = 1;             // streamed sources: drawn once streamed (frame times)
  uint64_t max_frames = 10000;     // then drawn as is, with a warning
  bool interactive =
      true;  // camera controls once drawn (0: the first view only, kept for captures)
  // Benches (?burst=K): each view frame drawn K times back to back, so that the GPU is kept busy
  // as native benchmarks keep it (a page drawing one frame an animation frame leaves it idle most
  // of the time, and its clocks low); the stats report the last of them.
  uint32_t burst = 1;
};

uint64_t number(const std::string& name, const char* value) {
  char* end = nullptr;
  // strtoull wraps a leading '-' around: refused, like anything that is not all digits.
  unsigned long long v = std::strtoull(value, &end, 10);
  if (!*value || *end || *value == '-') fail("{}: not a number: '{}'", name, value);
  return v;
}

double real_number(const std::string& name, const char* value) {
  char* end = nullptr;
  double v = std::strtod(value, &end);
  if (!*value || *end || !std::isfinite(v) || v <= 0)
    fail("{}: not a positive number: '{}'", name, value);
  return v;
}

// `stipple render`'s ranges for the same options (src/app/point_options.cpp).
float ranged_number(const std::string& name, const char* value, double lo, double hi) {
  char* end = nullptr;
  double v = std::strtod(value, &end);
  if (!*value || *end || !std::isfinite(v) || v < lo || v > hi)
    fail("{}: not a number in [{} - {}]: '{}'", name, lo, hi, value);
  return float(v);
}

Options parse(int argc, char** argv) {
  Options o;
  // The page's memory is at most 2 GiB (-sMAXIMUM_MEMORY): a cloud that needs more is refused
  // with the reason before it is read (the browser build has no pointlet cache).
  o.scene.host_memory = "2G";
  auto& render = o.scene.render;
  for (int i = 1; i < argc; ++i) {
    std::string a = argv[i];
    if (i + 1 >= argc) fail("{}: a value is missing", a);
    const char* v = argv[++i];
    if (a == "--width")
      o.view.width = uint32_t(number(a, v));
    else if (a == "--height")
      o.view.height = uint32_t(number(a, v));
    else if (a == "--scene-points")
      o.scene.scene_points = number(a, v);
    else if (a == "--seed")
      o.scene.seed = uint32_t(number(a, v));
    else if (a == "--url")
      o.urls.push_back(v);
    else if (a == "--canvas")
      o.canvas = v;
    else if (a == "--camera") {
      // Checked now, as `stipple render` checks it (used once the scene is loaded).
      scene::parse_numbers(v, 6, "--camera");
      o.view.camera = v;
    } else if (a == "--memory-mb")
      o.scene.memory_mb = number(a, v);
    else if (a == "--max-sse")
      o.scene.max_sse = real_number(a, v);
    else if (a == "--budget")
      o.scene.budget = number(a, v);
    else if (a == "--frames")
      o.frames = std::max<uint64_t>(1, number(a, v));
    else if (a == "--max-frames")
      o.max_frames = number(a, v);
    else if (a == "--burst")
      o.burst = uint32_t(std::clamp<uint64_t>(number(a, v), 1, 4));
    else if (a == "--interactive")
      o.interactive = number(a, v) != 0;
    else if (a == "--color")
      render.color = pc::parse_color_mode(v);
    else if (a == "--point-size")
      render.point_size = ranged_number(a, v, 0.0, 64.0);
    else if (a == "--edl")  // the page's checkbox: 1 on, 0 off
      render.edl = number(a, v) != 0;
    else if (a == "--no-edl")  // `stipple render --no-edl`, as ?no-edl=1
      render.edl = number(a, v) == 0;
    else if (a == "--edl-strength")
      render.edl_strength = ranged_number(a, v, 0.0, 10000.0);
    else if (a == "--edl-radius")
      render.edl_radius = ranged_number(a, v, 0.5, 16.0);
    // The rest of `stipple render`'s point options, by the same names and ranges: the renderer,
    // high-quality shading, hole filling and the occlusion check, how points are sized, the
    // filters (the tools' panel changes them afterwards).
    else if (a == "--renderer") {
      const std::string r = v;
      if (r == "auto")
        o.scene.renderer = scene::Renderer::Auto;
      else if (r == "billboard")
        o.scene.renderer = scene::Renderer::Billboard;
      else if (r == "compute")
        o.scene.renderer = scene::Renderer::Compute;
      else
        fail("--renderer: auto, billboard or compute: '{}'", r);
    } else if (a == "--raster-fallback") {
      // Benches: the compute rasterizer's 32-bit fallback even where the browser offers 64-bit
      // atomics (the variants compared in one page build).
      if (number(a, v) != 0) setenv("STIPPLE_RASTER_FALLBACK", "1", 1);
    } else if (a == "--splat-rasterizer") {
      const std::string r = v;
      o.scene.splat_rasterizer =
          r == "auto" ? std::nullopt
                      : std::optional<splats::SplatRasterizer>(splats::parse_splat_rasterizer(r));
    } else if (a == "--hqs")
      o.scene.hqs = number(a, v) != 0;
    else if (a == "--fill-radius")
      o.scene.fill_radius = int(ranged_number(a, v, 0.0, 8.0));
    else if (a == "--occlusion-beta")
      o.scene.occlusion_beta = ranged_number(a, v, 0.0, 1.5);
    else if (a == "--point-size-mode")
      render.size_mode = pc::parse_point_size_mode(v);
    else if (a == "--size-scale")
      render.size_scale = ranged_number(a, v, 0.01, 100.0);
    // The Nishita sky: ?sky=1, and its sun as ?sun=AZ,EL (degrees; the page has no PROJ to
    // place the data, so render's --sun-time is not taken here).
    else if (a == "--sky")
      render.sky.enabled = number(a, v) != 0;
    else if (a == "--sun") {
      const std::vector<double> sun = scene::parse_numbers(v, 2, "--sun");
      if (sun[1] < -90 || sun[1] > 90) fail("--sun: elevation must be in -90..90");
      render.sky.enabled = true;
      render.sky.sun_azimuth_deg = sun[0];
      render.sky.sun_elevation_deg = sun[1];
    } else if (a == "--classes")
      o.scene.filters.filter.classes = pc::parse_classes(v, "--classes");
    else if (a == "--returns")
      o.scene.filters.filter.returns = pc::parse_returns(v, "--returns");
    else if (a == "--intensity-filter")
      o.scene.filters.filter.intensity = pc::parse_range(v, "--intensity-filter");
    else if (a == "--clip-mode")
      o.scene.filters.mode = pc::parse_clip_mode(v);
    else
      fail("unknown option '{}'", a);
  }
  if (o.view.width == 0 || o.view.height == 0 || o.view.width > 8192 || o.view.height > 8192)
    fail("the image size must be 1..8192 pixels a side");
  if (o.scene.memory_mb == 0 || o.scene.memory_mb > (uint64_t(1) << 20))
    fail("--memory-mb: 1..1048576");
  return o;
}

void report(const char* key, const std::string& value) {
  EM_ASM({ Module.stippleReport(UTF8ToString($0), UTF8ToString($1)); }, key, value.c_str());
}

// What the module left in slot Module[`slot`] for the program (a value: taken, the slot emptied),
// as JSON; "" where the slot is empty.
std::string take_slot(const char* slot) {
  // (No commas outside parentheses in the JS: it is a macro argument.)
  char* text = static_cast<char*>(EM_ASM_PTR(
      {
        const name = UTF8ToString($0);
        const v = Module[name];
        if (v == null) return 0;
        Module[name] = null;
        return stringToNewUTF8(JSON.stringify(v));
      },
      slot));
  if (!text) return {};
  std::string value(text);
  std::free(text);
  return value;
}

// The slot's value parsed, or nullopt where it is empty or not what `valid` accepts (a warning
// naming the slot: the module checks what it puts there).
template <typename Valid>
std::optional<nlohmann::json> take_json(const char* slot, Valid valid) {
  const std::string text = take_slot(slot);
  if (text.empty()) return std::nullopt;
  nlohmann::json v = nlohmann::json::parse(text, nullptr, false);
  if (v.is_discarded() || !valid(v)) {
    STIPPLE_WARN("Module.{}: not understood: {}", slot, text);
    return std::nullopt;
  }
  return v;
}

// Whether the page asked for the canvas's pixels (viewer.pixels() and screenshot(), the tests'
// window.stippleCapture()): the view is drawn again and that frame read back, the page's only
// readback (a WebGPU canvas cannot be read through the page everywhere: headless Chromium on
// SwiftShader reads it blank).
bool take_capture_request() {
  return EM_ASM_INT({
    const c = Module.stippleCapture;
    if (!c || !c.wanted) return 0;
    c.wanted = false;
    return 1;
  });
}

// Draws the view again with its frame read back and hands the pixels to the page (RGBA, top row
// first). Returns false where no frame was drawn (the canvas had no texture): ask again.
bool draw_capture(Engine& engine) {
  engine.main().resource<ScreenshotRequests>().capture = true;
  engine.render().resource<CapturedFrame>().image = {};
  engine.update();
  const gpu::Image& image = engine.render().resource<CapturedFrame>().image;
  if (image.rgba.empty()) return false;
  EM_ASM(
      {
        const pixels = new Uint8ClampedArray(HEAPU8.subarray($2 >>> 0, ($2 >>> 0) + $0 * $1 * 4));
        Module.stippleCapture.deliver({width : $0, height : $1, data : pixels});
      },
      image.width, image.height, image.rgba.data());
  return true;
}

// The options the view now draws with (the module's viewer.options, the page's controls; JSON in
// setOptions' names): the colour mode asked for and the one shown (auto, or a mode the data
// lacks, resolves as in `stipple render`'s summary), EDL, its strength and radius, the point size
// in pixels and the point budget; for a streamed source its maximum screen-space error and
// memory budget.
void report_controls(Registry& main) {
  const auto& settings = main.resource<pc::PointDrawSettings>();
  const auto& render = settings.render;
  const char* shown = pc::color_mode_name(
      pc::resolve_color_mode(main.resource<pc::SceneInfo>().attributes, render.color));
  std::string stream;
  uint64_t budget = settings.budget;
  if (const auto* s = main.try_resource<tiles3d::TilesetStream>()) {
    const auto& t = s->streamer->traversal_options();
    budget = t.point_budget;
    stream = fmt::format(R"(,"maxSse":{:.6g},"memoryMb":{})", t.max_sse, t.memory_budget >> 20);
  }
  report("controls", fmt::format(R"({{"color":"{}","shown":"{}","edl":{},"edlStrength":{:.6g},)"
                                 R"("edlRadius":{:.6g},"pointSize":{:.6g},"budget":{}{}}})",
                                 pc::color_mode_name(render.color), shown, render.edl ? 1 : 0,
                                 double(render.edl_strength), double(render.edl_radius),
                                 double(render.point_size), budget, stream));
}

// The options the module changed since the last call (Module.stippleOptions: any of setOptions'
// names): applied to the draw settings (the colour mode and its ramps, EDL and the point size are
// uniforms of the next frame on both renderers, as in native `stipple view`'s panel: nothing is
// read or uploaded again), the point budget to what the next frame draws (a point cloud's
// nearest chunks on the point pipeline, as `stipple render --budget`; a streamed source's tile
// selection, as `stipple view`'s panel changes its traversal), the maximum screen-space error and
// memory budget to a streamed source's traversal. `stipple render`'s ranges (the module checks
// them first). Returns whether anything came (a frame is to be drawn).
bool take_options(Registry& main) {
  const auto o = take_json("stippleOptions", [](const nlohmann::json& v) { return v.is_object(); });
  if (!o) return false;
  auto& settings = main.resource<pc::PointDrawSettings>();
  auto& render = settings.render;
  // A finite number under `key`, clamped to [lo, hi].
  auto real = [&](const char* key, double lo, double hi) -> std::optional<double> {
    const auto it = o->find(key);
    if (it == o->end() || !it->is_number() || !std::isfinite(it->get<double>())) return {};
    return std::clamp(it->get<double>(), lo, hi);
  };
  if (const auto it = o->find("color"); it != o->end() && it->is_string()) {
    try {
      render.color = pc::parse_color_mode(it->get<std::string>());
    } catch (const std::exception& e) {
      STIPPLE_WARN("{}", e.what());
    }
  }
  if (const auto it = o->find("edl"); it != o->end() && it->is_boolean())
    render.edl = it->get<bool>();
  if (const auto v = real("edlStrength", 0.0, 1e4)) render.edl_strength = float(*v);
  if (const auto v = real("edlRadius", 0.5, 16.0)) render.edl_radius = float(*v);
  if (const auto v = real("pointSize", 0.0, 64.0); v && *v > 0) render.point_size = float(*v);
  const auto budget = real("budget", 0.0, 1e18);
  if (budget) settings.budget = uint64_t(*budget);
  if (auto* s = main.try_resource<tiles3d::TilesetStream>()) {
    tiles3d::TraversalOptions t = s->streamer->traversal_options();
    if (budget) t.point_budget = uint64_t(*budget);
    if (const auto v = real("maxSse", 1e-3, 1e6)) t.max_sse = *v;
    if (const auto v = real("memoryMb", 1.0, double(uint64_t(1) << 20)))
      t.memory_budget = uint64_t(*v) << 20;
    s->streamer->set_traversal_options(t);
  }
  report_controls(main);
  return true;
}

// The stats panel's figures (viewer.stats(), window.stipple.stats, JSON), those of native `stipple
// view`'s panel: the last drawn frame's time on the page's thread (cpuMs: the engine's update,
// which records and submits the frame without waiting for the GPU; frameMs, its older name, is the
// same figure), the GPU time of the newest frame whose timestamps have come back (gpuMs, the sum of
// its passes' times from timestamp queries, gpuPasses each pass's, and gpuFrame, that frame's
// number; null where the adapter has no timestamp queries (gpuTiming false) or none came back yet),
// frames per second (over the last half second of drawn frames: 0 while the view is idle), frames
// drawn so far (engine frames whose graph ran, a capture's included: it stops while the page is
// idle), points drawn of the scene's, for a tileset its tiles resident, loading and failed,
// resident bytes against the memory budget and the tiles' GPU bytes; the renderer and adapter, the
// canvas's size and format. Reported at most every 250 ms (`force`: now).
class StatsPanel {
 public:
  explicit StatsPanel(std::string renderer) : renderer_(std::move(renderer)) {}
  // A drawn frame's engine update took `ms`.
  void frame(double ms) {
    cpu_ms_ = ms;
    ++window_frames_;
  }
  void publish(Engine& engine, bool force = false) {
    // Timestamps that came back since the last frame (the browser delivers them while the page
    // waits for its next animation frame): an idle page shows its last frame's.
    drain_pass_times(engine, false);
    const double now = emscripten_get_now();
    if (window_start_ == 0) window_start_ = now;
    if (now - window_start_ >= 500) {
      fps_ = window_frames_ * 1e3 / (now - window_start_);
      window_start_ = now;
      window_frames_ = 0;
    }
    if (!force && now - last_ < 250) return;
    last_ = now;
    Registry& main = engine.main();
    const auto& render_stats = engine.render().resource<RenderStats>();
    const auto& d = main.resource<GpuContext>()->description;
    std::string tiles;
    if (const auto* stream = main.try_resource<tiles3d::TilesetStream>()) {
      const auto& stats = main.resource<tiles3d::TilesetStats>();
      const auto s = stream->streamer->stats();
      const auto* gpu = engine.render().try_resource<tiles3d::TilesetGpuStats>();
      tiles =
          fmt::format(R"(,"tilesDrawn":{},"tilesResident":{},"tilesLoading":{},"tilesFailed":{},)"
                      R"("residentBytes":{},"budgetBytes":{},"gpuBytes":{})",
                      stats.drawn_tiles, s.loaded, s.in_flight + s.queued, s.failed,
                      stats.resident_bytes, stats.memory_budget, gpu ? gpu->gpu_bytes : 0);
    }
    const bool timing = main.resource<GpuContext>()->has_feature(WGPUFeatureName_TimestampQuery);
    std::string gpu = fmt::format(R"("gpuTiming":{},"gpuMs":null,"gpuFrame":null)", timing);
    if (render_stats.pass_ms_frame > 0) {
      double gpu_ms = 0;
      std::string passes;
      for (const auto& [pass, ms] : render_stats.pass_ms) {
        gpu_ms += ms;
        passes += fmt::format(R"({}"{}":{:.3f})", passes.empty() ? "" : ",", pass, ms);
      }
      gpu = fmt::format(R"("gpuTiming":{},"gpuMs":{:.3f},"gpuFrame":{},"gpuPasses":{{{}}})", timing,
                        gpu_ms, render_stats.pass_ms_frame, passes);
    }
    const auto& canvas = engine.render().resource<web::CanvasInfo>();
    report("stats",
           fmt::format(R"({{"cpuMs":{:.2f},"frameMs":{:.2f},{},"fps":{:.1f},"frames":{},)"
                       R"("pointsDrawn":{},"points":{},"renderer":"{}","canvas":"{}x{} {}",)"
                       R"j("adapter":"{} {} ({})"{}}})j",
                       cpu_ms_, cpu_ms_, gpu, fps_, render_stats.frames, render_stats.points_drawn,
                       main.resource<pc::SceneInfo>().points, renderer_, canvas.width,
                       canvas.height, web::canvas_format_name(canvas.format), d.vendor,
                       d.architecture, d.backend, tiles));
  }

 private:
  std::string renderer_;
  double cpu_ms_ = 0, fps_ = 0, last_ = 0, window_start_ = 0;
  uint32_t window_frames_ = 0;
};

// The tile problems so far (failed tiles, content warnings), one line per kind with how many
// tiles had it: the first tile's message in full (it names the tile's URI).
std::string tile_problems(const tiles3d::TilesetStream& s) {
  std::string text;
  const std::string first_kind(tiles3d::tile_problem_kind(s.first_problem));
  for (const auto& [kind, count] : s.problems) {
    if (!text.empty()) text += '\n';
    text += kind == first_kind && !s.first_problem.empty() ? s.first_problem : kind;
    if (count > 1) text += fmt::format(" ({} tiles)", count);
  }
  return text;
}

// The camera controls' input since the last call (the module's listeners add it up, mouse and
// touch alike): turning drag in pixels, zoom steps (wheel, keys, pinch), panning drag in pixels
// (two fingers, or the mouse's right button).
struct Input {
  double dx = 0, dy = 0, zoom = 0, pan_x = 0, pan_y = 0;
};
Input take_input() {
  Input in;
  // (No commas outside parentheses in the JS: it is a macro argument.)
  EM_ASM(
      {
        const i = Module.stippleInput;
        if (!i) return;
        HEAPF64[$0 >> 3] = i.dx;
        HEAPF64[($0 >> 3) + 1] = i.dy;
        HEAPF64[($0 >> 3) + 2] = i.zoom;
        HEAPF64[($0 >> 3) + 3] = i.panX;
        HEAPF64[($0 >> 3) + 4] = i.panY;
        i.dx = i.dy = i.zoom = i.panX = i.panY = 0;
      },
      &in.dx);
  return in;
}

// The canvas's drawing-buffer size the module asks for (Module.stippleSize: its container's size
// in device pixels, times its scale), when it changed since the last call: set as the Viewport,
// which the canvas target configures the surface for before the next frame and the tileset's
// screen-space error follows. Returns whether the size changed (a frame is to be drawn).
bool take_resize(Registry& main) {
  uint32_t size[2] = {};
  // (No commas outside parentheses in the JS: it is a macro argument.)
  const int asked = EM_ASM_INT(
      {
        const s = Module.stippleSize;
        if (!s || !s.changed) return 0;
        s.changed = false;
        HEAPU32[$0 >> 2] = s.width;
        HEAPU32[($0 >> 2) + 1] = s.height;
        return 1;
      },
      size);
  if (!asked) return false;
  // The device's largest texture (and `--width`'s range) bounds the drawing buffer.
  const uint32_t largest =
      std::min<uint32_t>(8192, main.resource<GpuContext>()->limits.maxTextureDimension2D);
  const Viewport wanted{std::clamp<uint32_t>(size[0], 1, largest),
                        std::clamp<uint32_t>(size[1], 1, largest)};
  auto& viewport = main.resource<Viewport>();
  if (wanted.width == viewport.width && wanted.height == viewport.height) return false;
  viewport = wanted;
  return true;
}

// What the module asks to open next (Module.stippleOpen: a URL, or the path of a file it put in
// the instance's file system, dropped or chosen), or "" (then nothing is waiting).
std::string take_open() {
  const auto next = take_json("stippleOpen", [](const nlohmann::json& v) { return v.is_string(); });
  return next ? next->get<std::string>() : std::string();
}

// The camera's orbit: the point it turns about and looks at, and the camera's position from it
// as turn angles (radians, in the engine's Y-up world) and a distance. `moved`: the camera left
// the view it was framed with (a move or a set).
struct Orbit {
  glm::dvec3 target{0.0};
  double yaw = 0, pitch = 0, distance = 1;
  bool moved = false;
};

// The orbit of `camera` about `target`.
Orbit orbit_about(const Camera& camera, const glm::dvec3& target) {
  Orbit o;
  o.target = target;
  const glm::dvec3 offset = camera.position - target;
  o.distance = std::max(glm::length(offset), 1e-3);
  o.yaw = std::atan2(offset.x, offset.z);
  o.pitch = std::asin(std::clamp(offset.y / o.distance, -1.0, 1.0));
  return o;
}

// The orbit of the framed camera about the point of its view axis nearest `centre` (the data's):
// the view turns about the data without first swinging round to face its centre, and the target
// it reports lies on its view axis (viewer.camera: setting what it reads draws the same view).
Orbit first_orbit(Registry& main, const glm::dvec3& centre) {
  Camera camera;
  main.view<Camera>().each([&](const Camera& c) { camera = c; });
  const glm::dvec3 forward = camera.forward();
  double along = glm::dot(centre - camera.position, forward);
  if (!(along > 1e-3)) along = std::max(glm::length(centre - camera.position), 1e-3);
  return orbit_about(camera, camera.position + along * forward);
}

// The near plane for an eye and target (as `stipple render --camera` sets it).
double near_plane(const glm::dvec3& eye, const glm::dvec3& target) {
  return std::max(glm::length(target - eye) * 1e-4, 1e-3);
}

// The camera for the page (viewer.camera, window.stipple.camera, JSON): its position and target
// in the data's coordinates (Z up, as `stipple render --camera` takes them, to the last bit) and
// its vertical field of view in degrees; the orbit's turn angles (radians) and distance, and
// whether it left its first framing.
void report_camera(Registry& main, const Orbit& orbit) {
  Camera camera;
  main.view<Camera>().each([&](const Camera& c) { camera = c; });
  const glm::dvec3 p = y_up_to_z_up(camera.position), t = y_up_to_z_up(orbit.target);
  report("camera", fmt::format(R"({{"position":[{:.17g},{:.17g},{:.17g}],)"
                               R"("target":[{:.17g},{:.17g},{:.17g}],"fov":{:.17g},)"
                               R"("yaw":{:.6f},"pitch":{:.6f},"distance":{:.17g},"moved":{}}})",
                               p.x, p.y, p.z, t.x, t.y, t.z, glm::degrees(camera.fov_y), orbit.yaw,
                               orbit.pitch, orbit.distance, orbit.moved));
}

// A camera the module set (Module.stippleCamera: {position, target} in the data's coordinates,
// Z up, and optionally fov in degrees), since the last call: the camera looks from the position
// at the target, which the orbit turns about from then on. Returns whether one came.
bool take_camera(Registry& main, Orbit& orbit) {
  const auto finite3 = [](const nlohmann::json& v) {
    if (!v.is_array() || v.size() != 3) return false;
    for (const auto& x : v)
      if (!x.is_number() || !std::isfinite(x.get<double>())) return false;
    return true;
  };
  const auto c = take_json("stippleCamera", [&](const nlohmann::json& v) {
    return v.is_object() && finite3(v.value("position", nlohmann::json())) &&
           finite3(v.value("target", nlohmann::json()));
  });
  if (!c) return false;
  const auto& p = (*c)["position"];
  const auto& t = (*c)["target"];
  const glm::dvec3 eye = z_up_to_y_up({p[0].get<double>(), p[1].get<double>(), p[2].get<double>()});
  const glm::dvec3 target =
      z_up_to_y_up({t[0].get<double>(), t[1].get<double>(), t[2].get<double>()});
  if (glm::length(target - eye) <= 0.0) {
    STIPPLE_WARN("camera: the position and target are the same point");
    return false;
  }
  Camera camera;
  main.view<Camera>().each([&](Camera& cam) {
    cam.look_at(eye, target);
    cam.near_plane = near_plane(eye, target);
    if (const auto fov = c->find("fov"); fov != c->end() && fov->is_number()) {
      const double deg = fov->get<double>();
      if (std::isfinite(deg) && deg > 0 && deg < 180) cam.fov_y = glm::radians(deg);
    }
    camera = cam;
  });
  orbit = orbit_about(camera, target);
  orbit.moved = true;
  return true;
}

// Once the view is drawn: the camera orbits `orbit.target` (drag turns it, the wheel, keys and
// pinch zoom, a two-finger or right-button drag moves the target across the view), or goes where
// the module sets it. One engine frame per animation frame when something changed: the camera, an
// option, the canvas's size, or, for a tileset streaming for the new view (`streams`), a tile
// arrived, or a splat frame lost tile pairs (splats::splat_frames_incomplete); none otherwise
// (the canvas keeps the last frame). Returns what to open next, once the module has something.
std::string orbit_view(Engine& engine, Orbit orbit, bool streams, uint32_t burst,
                       StatsPanel& panel) {
  Registry& main = engine.main();
  report_camera(main, orbit);
  uint64_t moves = 0, frames = 0;
  bool capture = false;  // asked for and not yet drawn
  for (;;) {
    next_frame();
    panel.publish(engine);
    if (std::string next = take_open(); !next.empty()) return next;
    const bool restyled = take_options(main);
    const bool resized = take_resize(main);
    const bool set = take_camera(main, orbit);
    // The tools first: while they hold the pointer (a vertex dragged) the camera stays.
    bool holds_pointer = false;
    const bool tooled = web::take_tool_commands(engine, holds_pointer);
    Input in = take_input();
    if (holds_pointer) in = {};
    const bool turned = in.dx != 0 || in.dy != 0 || in.zoom != 0 || in.pan_x != 0 || in.pan_y != 0;
    if (turned) {
      Camera camera;
      main.view<Camera>().each([&](const Camera& c) { camera = c; });
      orbit.yaw -= in.dx * 0.005;
      orbit.pitch = std::clamp(orbit.pitch + in.dy * 0.005, -1.55, 1.55);
      orbit.distance *= std::exp(in.zoom * 0.1);
      const glm::dvec3 dir(std::cos(orbit.pitch) * std::sin(orbit.yaw), std::sin(orbit.pitch),
                           std::cos(orbit.pitch) * std::cos(orbit.yaw));
      if (in.pan_x != 0 || in.pan_y != 0) {
        // A pixel at the target's depth, in world units: the points under the fingers follow
        // them. (The view is never straight up or down: pitch stops short of the poles.)
        // (The page sends the drag in the canvas's pixels.)
        const double height = double(main.resource<Viewport>().height);
        const double pixel = 2.0 * orbit.distance * std::tan(camera.fov_y / 2) / height;
        const glm::dvec3 right = glm::normalize(glm::cross(-dir, glm::dvec3(0, 1, 0)));
        const glm::dvec3 up = glm::cross(right, -dir);
        orbit.target += (-in.pan_x * right + in.pan_y * up) * pixel;
      }
      const glm::dvec3 eye = orbit.target + orbit.distance * dir;
      main.view<Camera>().each([&](Camera& c) {
        c.look_at(eye, orbit.target);
        c.near_plane = near_plane(eye, orbit.target);
      });
      orbit.moved = true;
    }
    const bool moved = turned || set;
    if (moved) {
      report("cameraMoves", std::to_string(++moves));
      report_camera(main, orbit);
    }
    // Loads under way draw nothing until one finishes (the frame that takes it in): a streamed
    // point source's tiles, and a splat tileset's (which streams beside a point cloud drawn once).
    const auto* splat_stream = main.try_resource<tiles3d::StreamedSplats>();
    const bool arrived =
        (streams && main.resource<tiles3d::TilesetStream>().streamer->has_results()) ||
        (splat_stream && splat_stream->streamer && splat_stream->streamer->has_results());
    // A splat frame that lost tile pairs (its count came back since, the buffers have grown):
    // drawn once more.
    const bool incomplete = splats::splat_frames_incomplete(engine);
    if (!moved && !restyled && !resized && !arrived && !tooled && !incomplete) {
      web::report_tools(engine);  // a tool chosen, a message: nothing to draw
      // A capture draws the unchanged view again: not a view frame (viewFrames, frame time).
      capture = capture || take_capture_request();
      if (capture && draw_capture(engine)) {
        capture = false;
        panel.publish(engine, true);  // the frames drawn count it
      }
      continue;
    }
    const double start = emscripten_get_now();
    engine.update();
    if (!streams) engine.wait_for_render();
    panel.frame(emscripten_get_now() - start);
    for (uint32_t i = 1; i < burst; ++i) {
      engine.update();
      if (!streams) engine.wait_for_render();
    }
    web::report_tools(engine);
    web::report_overlay(engine);
    // Frames drawn since the first view (tests wait for the one after a control's change).
    report("viewFrames", std::to_string(++frames));
    // A splat tileset's splats drawn now, and whether its loads for this view are done.
    if (splat_stream) {
      report("streamedSplats", std::to_string(splat_stream->drawn_splats));
      report("splatsIdle", splat_stream->idle ? "1" : "0");
    }
    panel.publish(engine, true);
  }
}

// Until the module has something to open (after an error).
std::string wait_for_open() {
  for (;;) {
    next_frame();
    if (std::string next = take_open(); !next.empty()) return next;
  }
}

// The centre of what a streamed source draws now (else its volume's).
glm::dvec3 drawn_centre(Registry& main) {
  Aabb drawn;
  const auto& s = main.resource<tiles3d::TilesetStream>();
  for (uint32_t t : s.draw)
    for (const auto& chunk : s.chunks[t]->chunks) drawn.extend(chunk.bounds);
  return drawn.empty() ? s.world_bounds.center() : drawn.center();
}

// The page's view of `o`: the scene assembled as `stipple render` assembles it (scene::
// plan_scene, add_scene_plugin, place_camera; for a streamed source settle_streamed_scene), drawn
// on the page's canvas. A point cloud is drawn once; a streamed source one engine frame per
// animation frame while its tiles stream in, until it has settled and `frames` more frames are
// drawn. What the module asked for before (a link's view state, options set while no view was
// open: the options and camera slots) applies on top of the scene as loaded, as if changed once
// it was drawn: so the renderer, framing and automatic point size are those of the plain view,
// and a link draws what its sender saw. Then it reports done and, when interactive, the camera
// follows the module's input; otherwise the view is kept (never returning) to be drawn again for
// the module's captures. Returns what to open next.
std::string run_view(const Options& o) {
  Engine engine;
  // Frames are not waited for (each wait would be a round trip through the browser's GPU
  // process): their timestamps come back a few frames later. The last frames' times are kept,
  // for the streamed view's GPU time once settled.
  scene::add_engine_core(engine,
                         {.keep_history = true, .history_limit = 256, .wait_for_gpu = false});
  Registry& main = engine.main();
  scene::ScenePlan plan = scene::plan_scene(o.scene, *main.resource<GpuContext>());
  const bool streamed = plan.source.streamed();
  // The file read (a LAZ decoded by LASzip) or the scene generated: loadMs on the page.
  const double load_start = emscripten_get_now();
  scene::add_scene_plugin(engine, plan);
  const double load_ms = emscripten_get_now() - load_start;
  // Drawn into the page's canvas, sized as the module asks (take_resize).
  engine.add_plugin(web::CanvasTargetPlugin{o.canvas, o.view.width, o.view.height});
  scene::place_camera(engine, plan, o.view, true);
  // The tools (tools_bridge.cpp is the page's layer over them); exports on the page's thread.
  tools::ToolsCorePlugin tools_plugin;
  tools_plugin.background_exports = false;
  engine.add_plugin(std::move(tools_plugin));
  const char* renderer = plan.compute() ? "compute" : "billboard";
  // Splats: the rasterizer asked for, else the device's (before "renderer", the first report).
  if (!plan.splats.empty() || !plan.splat_tileset.empty())
    report("splatRasterizer", splats::splat_rasterizer_name(plan.options.splat_rasterizer.value_or(
                                  splats::default_splat_rasterizer(*main.resource<GpuContext>()))));
  report("renderer", renderer);
  StatsPanel panel(renderer);
  auto report_adapter = [&] {
    const gpu::Context& ctx = *main.resource<GpuContext>();
    const auto& d = ctx.description;
    report("adapter", fmt::format("{} {} ({})", d.vendor, d.architecture, d.backend));
    // The compute rasterizer's depth pass: 64-bit where the browser offers atomic-vec2u-min-max.
    report("visibility", !pc::has_visibility64(ctx) ? "32-bit fallback"
                         : ctx.has_feature(gpu::kFeatureAtomicVec2uMinMax)
                             ? "64-bit (atomic<vec2u>)"
                             : "64-bit");
  };
  const double start = emscripten_get_now();
  Orbit orbit;
  if (!streamed) {
    // The renderer, camera and point size are chosen: the module's options and camera apply
    // before the first frame.
    orbit = first_orbit(main, main.resource<pc::SceneInfo>().world_bounds.center());
    take_options(main);
    take_camera(main, orbit);
    if (!plan.splat_tileset.empty()) {
      // A splat tileset streams in: one engine frame per animation frame until it is idle.
      for (uint64_t f = 0;; ++f) {
        engine.update();
        const auto& s = main.resource<tiles3d::StreamedSplats>();
        report("progress", fmt::format("{} tiles, {} splats{}", s.drawn_tiles, s.drawn_splats,
                                       s.idle ? "" : ", loading"));
        if (s.idle || f + 1 >= o.max_frames) break;
        next_frame();
      }
    } else {
      engine.run(1);
    }
    const double ms = emscripten_get_now() - start;
    if (engine.render().resource<RenderStats>().frames == 0) fail("no frame was drawn");
    report_adapter();
    report("points", std::to_string(main.resource<pc::SceneInfo>().points));
    report("splats", std::to_string(plan.splat_count() + scene::drawn_splats(main)));
    report("pointSize",
           fmt::format("{:.3f}", main.resource<pc::PointDrawSettings>().render.point_size));
    report("ms", fmt::format("{:.1f}", ms));
    report("loadMs", fmt::format("{:.1f}", load_ms));
    panel.frame(ms);
  } else {
    scene::settle_streamed_scene(engine, plan, o.view, o.max_frames);
    std::vector<double> settled_ms;  // frame times once streamed (the engine's update)
    uint64_t first_settled = 0;      // the number of the first frame drawn once streamed
    size_t problems = 0;
    // Frames until streamed and `frames` more drawn; then once more where the module's options
    // or camera came (they apply once streamed: the refitted camera and the point size fitted to
    // the tiles are the plain view's), until streamed for them.
    uint64_t until = o.frames;
    bool applied = false;
    for (;;) {
      take_resize(main);  // the canvas follows the page while the tiles stream in
      const double frame_start = emscripten_get_now();
      engine.update();
      const auto& settle = main.resource<scene::StreamSettle>();
      // Frames drawn once streamed (the settling system ran before this frame was drawn).
      if (settle.settled > 0) {
        settled_ms.push_back(emscripten_get_now() - frame_start);
        if (first_settled == 0) first_settled = engine.render().resource<RenderStats>().frames;
      }
      panel.frame(emscripten_get_now() - frame_start);
      panel.publish(engine);
      const auto& s = main.resource<tiles3d::TilesetStream>();
      const auto& stats = main.resource<tiles3d::TilesetStats>();
      size_t n = 0;
      for (const auto& [kind, count] : s.problems) n += count;
      if (n != problems) {
        problems = n;
        report("tileProblems", tile_problems(s));
      }
      report("progress", fmt::format("{} tiles, {} points{}", stats.drawn_tiles, stats.drawn_points,
                                     stats.idle ? "" : ", loading"));
      if (settle.settled >= until) {
        if (applied) break;
        applied = true;
        orbit = first_orbit(main, drawn_centre(main));
        const bool restyled = take_options(main);
        if (!take_camera(main, orbit) && !restyled) break;
        until = settle.settled + o.frames;
      }
      next_frame();
      if (std::string next = take_open(); !next.empty()) return next;
    }
    drain_pass_times(engine);  // the settled frames' GPU times
    const auto& stats = main.resource<tiles3d::TilesetStats>();
    report_adapter();
    report("tiles", std::to_string(stats.drawn_tiles));
    report("points", std::to_string(stats.drawn_points));
    report("errors", std::to_string(stats.errors));
    report("pointSize",
           fmt::format("{:.3f}", main.resource<pc::PointDrawSettings>().render.point_size));
    report("ms", fmt::format("{:.1f}", emscripten_get_now() - start));
    // Medians once streamed: the page's thread per frame (cpuMs; frameMs, its older name) and,
    // where the adapter has timestamp queries, the GPU's (gpuMs).
    if (!settled_ms.empty()) {
      std::sort(settled_ms.begin(), settled_ms.end());
      report("frameMs", fmt::format("{:.1f}", settled_ms[settled_ms.size() / 2]));
      report("cpuMs", fmt::format("{:.2f}", settled_ms[settled_ms.size() / 2]));
      const auto& render_stats = engine.render().resource<RenderStats>();
      std::vector<double> gpu_ms;
      for (size_t i = 0; i < render_stats.gpu_ms.size(); ++i)
        if (render_stats.gpu_frames[i] >= first_settled) gpu_ms.push_back(render_stats.gpu_ms[i]);
      if (first_settled > 0 && !gpu_ms.empty()) {
        std::sort(gpu_ms.begin(), gpu_ms.end());
        report("gpuMs", fmt::format("{:.3f}", gpu_ms[gpu_ms.size() / 2]));
        // And each pass's median over the same frames (JSON: name to ms), for benches.
        std::string passes;
        for (const auto& [pass, times] : render_stats.history) {
          if (times.size() < gpu_ms.size()) continue;  // not in every settled frame
          std::vector<double> last(times.end() - std::ptrdiff_t(gpu_ms.size()), times.end());
          std::sort(last.begin(), last.end());
          passes += fmt::format(R"({}"{}":{:.3f})", passes.empty() ? "" : ",", pass,
                                last[last.size() / 2]);
        }
        report("gpuPassesMs", "{" + passes + "}");
      }
    }
  }
  report_controls(main);
  panel.publish(engine, true);
  web::report_tools(engine, true);
  report("done", "1");
  std::string next;
  if (o.interactive) {
    next = orbit_view(engine, orbit, streamed, o.burst, panel);
  } else {
    // The view stays as drawn, kept only to be drawn again for the module's captures.
    report_camera(main, orbit);
    for (bool capture = false;;) {
      next_frame();
      capture = capture || take_capture_request();
      if (capture && draw_capture(engine)) {
        capture = false;
        panel.publish(engine, true);
      }
    }
  }
  engine.shutdown();
  return next;
}

// A LAS file by URL (.las/.laz, case aside): read whole like `stipple render file.las` does.
// (COPC by URL, named .copc.laz, streams.)
bool is_las_url(const std::string& url) {
  std::string path = io::uri_path(url);
  for (auto& c : path) c = char(std::tolower(static_cast<unsigned char>(c)));
  return (path.ends_with(".las") || path.ends_with(".laz")) && !path.ends_with(".copc.laz");
}

// Whether what the module asks to open is a URL (else a path in the instance's file system).
bool is_url(const std::string& s) {
  return s.starts_with("http://") || s.starts_with("https://") || s.starts_with("blob:");
}

// Fetches `url` (the browser's fetch) into a file of the page's in-memory file system, which
// the LAS reader opens like any file; returns its path.
std::string fetch_to_memory(const std::string& url) {
  io::FetchOptions options;
  options.max_bytes = uint64_t(2) << 30;
  const std::vector<uint8_t> bytes = io::fetch(url, options);
  std::string name = io::uri_path(url);
  name = name.substr(name.find_last_of('/') + 1);
  std::filesystem::create_directories("/input");
  if (name.empty()) name = "input.las";
  // Several files of one name (from different folders) each keep theirs.
  std::string path = "/input/" + name;
  for (int n = 2; std::filesystem::exists(path); ++n) path = fmt::format("/input/{}-{}", n, name);
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
  if (!out) fail("{}: cannot be kept in the page's memory ({} bytes)", url, bytes.size());
  return path;
}

// One view after another: the first source (--url, or the built-in scene), then each the module
// asks for. An error is shown and the program waits for something to open instead. Returns once
// the module asked it to end (Quit), or where it cannot go on.
int run(Options& o) {
  for (;;) {
    std::string next;
    try {
      // A LAS/LAZ URL is fetched into the page's file system first and read whole there, as
      // `stipple render file.laz` reads it; what is streamed is opened by its URL.
      if (!o.urls.empty()) {
        o.scene.inputs.clear();
        // The files fetched for the view before go (the page's memory holds one view's).
        std::error_code ec;
        std::filesystem::remove_all("/input", ec);
        for (const std::string& url : o.urls) {
          if (o.urls.size() > 1 && !is_las_url(url))
            fail(
                "{}: several sources at once are LAS/LAZ files (a tileset, COPC, EPT or Potree "
                "source streams alone)",
                url);
          o.scene.inputs.push_back(is_las_url(url) ? fetch_to_memory(url) : url);
        }
      }
      o.urls.clear();
      next = run_view(o);
    } catch (const Quit&) {
      return 0;
    } catch (const std::exception& e) {
      std::fprintf(stderr, "stipple: %s\n", e.what());
      report("error", e.what());
      if (!o.interactive) return 1;
      try {
        next = wait_for_open();
      } catch (const Quit&) {
        return 0;
      }
    }
    if (next.empty()) return 0;
    // A URL in place of --url; a file of the instance's file system in place of the inputs.
    if (is_url(next))
      o.urls = {next};
    else
      o.scene.inputs = {next};
    // --camera was the first source's: the next is framed (or gets the module's camera).
    o.view.camera.clear();
  }
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  try {
    o = parse(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "stipple: %s\n", e.what());
    report("error", e.what());
    return 1;
  }
  const int status = run(o);
  // The runtime exits even where a browser callback still holds it (a request in flight): the
  // instance's threads end with it.
  emscripten_force_exit(status);
  return status;
}
