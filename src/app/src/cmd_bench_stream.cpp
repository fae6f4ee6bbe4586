// `stipple bench stream`: a 3D Tiles tileset or a COPC file streamed along seed 002's camera
// path (an orbit while the field of view zooms), drawn headless by the compute rasterizer (LOD
// batches) or by billboards. Frames do not wait for loads (as in a viewer): each frame is one
// engine update, timed; the summary is FPS statistics (average, min, max, 1% and 0.1% lows),
// GPU ms, drawn and resident points, loads and evictions, peak resident bytes and RSS.
// `--samples FILE.csv` adds a row every `--sample-seconds` (and after the last frame): the
// process's RSS, the resident tile bytes against the budget, the tiles' GPU bytes as the
// allocators account them, loads, evictions and errors (bench/soak.sh checks every row).
#include <algorithm>
#include <array>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <map>
#include <memory>
#include <numeric>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "stipple/app/camera_path.hpp"
#include "stipple/app/commands.hpp"
#include "stipple/app/scene.hpp"
#include "stipple/core/atomic_file.hpp"
#include "stipple/core/error.hpp"
#include "stipple/core/memory.hpp"
#include "stipple/core/progress.hpp"
#include "stipple/core/stats.hpp"
#include "stipple/engine/camera.hpp"
#include "stipple/engine/engine.hpp"
#include "stipple/engine/plugins.hpp"
#include "stipple/engine/render_plugins.hpp"
#include "stipple/pointcloud/compute_raster.hpp"
#include "stipple/pointcloud/scene.hpp"
#include "stipple/tiles3d/splat_stream.hpp"
#include "stipple/tiles3d/tileset_plugin.hpp"

namespace stipple::app {
namespace {

struct StreamBenchArgs {
  std::string input;
  std::string renderer = "compute";
  uint32_t width = 1920, height = 1080;
  uint32_t frames = 600;
  CameraPath path;
  double max_sse = 0;  // 0: the source's default
  uint64_t memory_mb = 4096, budget = 0, splat_budget = 0;
  std::string backend, json;
  std::string samples;
  double sample_seconds = 1.0;
  double duration = 0;  // seconds; 0: every frame of --frames
  FrameMode mode;
};

// The per-interval samples, written and flushed row by row so that a long run can be watched
// (and a crash keeps what came before it).
class SampleWriter {
 public:
  explicit SampleWriter(const std::string& path) : path_(path) {
    if (path.empty()) return;
    file_ = std::fopen(path.c_str(), "w");
    if (!file_) fail("bench stream: cannot write {}: {}", path, std::strerror(errno));
    std::fputs(
        "seconds,frame,rss_bytes,resident_bytes,memory_budget,gpu_bytes,gpu_reserved_bytes,"
        "resident_tiles,gpu_tiles,loads,evictions,errors,refused_uploads\n",
        file_);
  }
  ~SampleWriter() {
    if (file_) std::fclose(file_);
  }
  SampleWriter(const SampleWriter&) = delete;
  SampleWriter& operator=(const SampleWriter&) = delete;
  explicit operator bool() const { return file_ != nullptr; }
  void write(double seconds, uint32_t frame, const tiles3d::TilesetStats& s,
             const tiles3d::TilesetGpuStats* g) {
    const auto u = [](uint64_t v) { return static_cast<unsigned long long>(v); };
    const int n = std::fprintf(
        file_, "%.3f,%u,%llu,%llu,%llu,%llu,%llu,%u,%u,%llu,%llu,%llu,%llu\n", seconds, frame,
        u(resident_bytes()), u(s.resident_bytes), u(s.memory_budget), u(g ? g->gpu_bytes : 0),
        u(g ? g->gpu_reserved_bytes : 0), s.resident_tiles, g ? g->gpu_tiles : 0u,
        u(s.loads_completed), u(s.evictions), u(s.errors), u(g ? g->refused_uploads : 0));
    if (n < 0 || std::fflush(file_) != 0)
      fail("bench stream: cannot write {}: {}", path_, std::strerror(errno));
  }

 private:
  std::string path_;
  std::FILE* file_ = nullptr;
};

// A splat tileset's stream in the figures of a point tileset's (loads, evictions, bytes; the
// drawn "points" are splats).
tiles3d::TilesetStats splat_stream_stats(Registry& main) {
  const auto& s = main.resource<tiles3d::StreamedSplats>();
  const tiles3d::StreamerStats st = s.streamer->stats();
  tiles3d::TilesetStats out;
  out.frames = s.frames;
  out.resident_tiles = s.resident_tiles;
  out.resident_bytes = st.resident_bytes;
  out.peak_resident_bytes = st.peak_resident_bytes;
  out.memory_budget = s.streamer->traversal_options().memory_budget;
  out.loads_completed = st.loads_completed;
  out.evictions = st.evictions;
  out.discarded_over_budget = st.discarded_over_budget;
  out.budget_limited = st.budget_limited;
  out.sse_threshold = st.sse_threshold;
  out.drawn_tiles = s.drawn_tiles;
  out.drawn_points = s.drawn_splats;
  out.idle = s.idle;
  out.errors = s.errors;
  return out;
}

void run_stream_bench(const StreamBenchArgs& a) {
  Engine engine;
  add_engine_core(engine, bench_engine_core(a.backend, a.mode));
  SceneOptions scene;
  scene.inputs = {a.input};
  scene.renderer = a.renderer == "compute" ? Renderer::Compute : Renderer::Billboard;
  scene.max_sse = a.max_sse;
  scene.memory_mb = a.memory_mb;
  scene.budget = a.budget;
  scene.splat_budget = a.splat_budget;
  scene.render.point_size = a.renderer == "compute" ? 1.0f : 2.0f;
  const ScenePlan plan = plan_scene(scene, *engine.render().resource<GpuContext>());
  // A splat tileset streams through tiles3d::SplatTilesetPlugin (the splats drawn, sorted
  // together, each frame), its figures in TilesetStats' form.
  const bool splat = !plan.splat_tileset.empty();
  if (!plan.source.streamed() && !splat)
    fail("bench stream: {} is not a tileset or a COPC file, nor a Potree or EPT cloud", a.input);
  if (splat && !a.samples.empty())
    fail("bench stream: --samples is for point tilesets (the tiles' GPU memory)");
  auto tileset_stats = [splat](Registry& main) {
    return splat ? splat_stream_stats(main) : main.resource<tiles3d::TilesetStats>();
  };
  if (a.mode.pipelined && !a.samples.empty())
    fail(
        "bench stream: --samples reads the render world every frame, which --pipelined runs on "
        "its own thread");
  add_scene_plugin(engine, plan);
  engine.add_plugin(HeadlessTargetPlugin{a.width, a.height, "", 0});

  Registry& main = engine.main();
  Registry& render = engine.render();
  const Aabb world = main.resource<pc::SceneInfo>().world_bounds;
  const double aspect = double(a.width) / a.height;
  const Entity camera = main.create();
  main.emplace<Camera>(camera, path_camera(a.path, world, 0.0, aspect));
  std::vector<double> wall_ms, gpu_ms;
  std::vector<uint64_t> drawn;
  SampleWriter samples(a.samples);
  const auto start = std::chrono::steady_clock::now();
  double next_sample = 0.0;
  Progress progress("streaming", a.frames, "frames");
  uint32_t frames = a.frames, sampled = 0;
  for (uint32_t f = 0; f < a.frames; ++f) {
    // With --duration the path runs by the clock, so that the whole flight fits the time
    // however fast the frames come (a soak on a loaded machine); else by frame.
    const std::optional<double> along = flight_along(
        a.duration, std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(),
        f, a.frames);
    if (!along) {
      frames = f;  // the time is up: the path stops here
      break;
    }
    main.get<Camera>(camera) = path_camera(a.path, world, *along, aspect);
    const auto t0 = std::chrono::steady_clock::now();
    engine.update();
    wall_ms.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    drawn.push_back(tileset_stats(main).drawn_points);
    if (samples) {
      const double now =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      if (now >= next_sample || f + 1 == a.frames) {
        samples.write(now, f + 1, main.resource<tiles3d::TilesetStats>(),
                      render.try_resource<tiles3d::TilesetGpuStats>());
        sampled = f + 1;
        next_sample = a.sample_seconds > 0 ? now + a.sample_seconds : 0.0;
      }
    }
    progress.advance(1);
  }
  progress.finish();
  if (samples && sampled != frames)  // --duration ended the run between samples
    samples.write(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(),
                  frames, main.resource<tiles3d::TilesetStats>(),
                  render.try_resource<tiles3d::TilesetGpuStats>());
  // Every timed frame's GPU ms (RenderStats' history), once the render world is idle and the
  // timestamps still on their way (frames that do not wait for the GPU) are in.
  drain_pass_times(engine);
  gpu_ms = render.resource<RenderStats>().gpu_ms;
  // Each pass's median over the frames that ran it (where the GPU's frame goes).
  std::map<std::string, double> pass_median;
  for (const auto& [pass, times] : render.resource<RenderStats>().history)
    if (!times.empty()) pass_median[pass] = median(times);
  const auto stats = tileset_stats(main);
  // The frame's CPU by stage (where a frame's wall beyond its GPU time goes), read while the
  // render world is idle.
  engine.wait_for_render();
  const double main_cpu = engine.main_cpu_ms() / std::max<size_t>(wall_ms.size(), 1);
  std::array<double, 5> render_cpu = engine.render_cpu_ms();
  for (double& ms : render_cpu) ms /= double(std::max<size_t>(wall_ms.size(), 1));
  engine.shutdown();

  const double total = std::accumulate(wall_ms.begin(), wall_ms.end(), 0.0);
  const double avg = total > 0 ? 1000.0 * double(wall_ms.size()) / total : 0;
  const double slowest = *std::max_element(wall_ms.begin(), wall_ms.end());
  const double fastest = *std::min_element(wall_ms.begin(), wall_ms.end());
  const double gpu_median = median(gpu_ms);
  const double drawn_mean =
      double(std::accumulate(drawn.begin(), drawn.end(), uint64_t(0))) / double(drawn.size());
  const uint64_t rss = peak_resident_bytes();
  const char* mode = a.mode.name();
  std::printf("%s (%s, %ux%u, %u frames, %s)\n", a.input.c_str(), a.renderer.c_str(), a.width,
              a.height, frames, mode);
  std::printf(
      "  FPS avg %.1f, min %.1f, max %.1f, 1%% low %.1f, 0.1%% low %.1f; GPU %.3f ms (median)\n",
      avg, 1000.0 / slowest, 1000.0 / fastest, low_fps(wall_ms, 0.01), low_fps(wall_ms, 0.001),
      gpu_median);
  std::printf(
      "  drawn %.2f M %s a frame (mean); %llu loads, %llu evictions, %llu errors; peak "
      "resident %.1f MiB of %.1f; RSS %.1f MiB\n",
      drawn_mean / 1e6, splat ? "splats" : "points",
      static_cast<unsigned long long>(stats.loads_completed),
      static_cast<unsigned long long>(stats.evictions),
      static_cast<unsigned long long>(stats.errors), stats.peak_resident_bytes / 1048576.0,
      stats.memory_budget / 1048576.0, rss / 1048576.0);
  std::printf(
      "  CPU ms a frame by stage: main %.3f | render Prepare %.3f, Queue %.3f, PreDraw %.3f, Draw "
      "%.3f, PostDraw %.3f\n",
      main_cpu, render_cpu[0], render_cpu[1], render_cpu[2], render_cpu[3], render_cpu[4]);
  std::string passes;
  for (const auto& [pass, ms] : pass_median)
    passes += fmt::format("{}{} {:.3f}", passes.empty() ? "" : ", ", pass, ms);
  std::printf("  GPU ms by pass (median): %s\n", passes.c_str());
  if (!a.json.empty()) {
    nlohmann::json j;
    j["input"] = a.input;
    j["renderer"] = a.renderer;
    j["width"] = a.width;
    j["height"] = a.height;
    j["frames"] = frames;
    j["pipelined"] = a.mode.pipelined;
    j["gpu_wait"] = a.mode.waits_for_gpu();
    j["fps"] = {{"average", avg},
                {"min", 1000.0 / slowest},
                {"max", 1000.0 / fastest},
                {"low_1pct", low_fps(wall_ms, 0.01)},
                {"low_0_1pct", low_fps(wall_ms, 0.001)}};
    j["gpu_ms_median"] = gpu_median;
    j["gpu_pass_ms_median"] = pass_median;
    j["frame_wall_ms"] = wall_ms;
    j["frame_gpu_ms"] = gpu_ms;
    j[splat ? "splats_drawn_mean" : "points_drawn_mean"] = drawn_mean;
    j["loads"] = stats.loads_completed;
    j["evictions"] = stats.evictions;
    j["errors"] = stats.errors;
    j["peak_resident_bytes"] = stats.peak_resident_bytes;
    j["memory_budget"] = stats.memory_budget;
    j["peak_rss_bytes"] = rss;
    j["cpu_ms_mean"] = {{"main_stages", main_cpu},       {"render_prepare", render_cpu[0]},
                        {"render_queue", render_cpu[1]}, {"render_predraw", render_cpu[2]},
                        {"render_draw", render_cpu[3]},  {"render_postdraw", render_cpu[4]}};
    write_file_atomically(a.json, j.dump(1));
  }
}

}  // namespace

void add_bench_stream_command(CLI::App& bench) {
  auto a = std::make_shared<StreamBenchArgs>();
  auto* cmd = bench.add_subcommand(
      "stream", "A tileset or COPC file streamed along the seed's camera path: FPS statistics");
  cmd->add_option("input", a->input,
                  "tileset.json (path or URL; a local splat tileset streams its splats) or COPC "
                  "file")
      ->required();
  cmd->add_option("--renderer", a->renderer, "compute (LOD batches) or billboard")
      ->check(CLI::IsMember({"compute", "billboard"}))
      ->capture_default_str();
  cmd->add_option("--width", a->width, "Image width")->capture_default_str();
  cmd->add_option("--height", a->height, "Image height")->capture_default_str();
  cmd->add_option("--frames", a->frames, "Frames along the path")
      ->check(CLI::Range(1u, 1000000u))
      ->capture_default_str();
  add_camera_path_options(cmd, a->path);
  cmd->add_option("--max-sse", a->max_sse,
                  "Screen-space error threshold (pixels; default 16 for 3D Tiles, 2 for COPC)");
  cmd->add_option("--memory-mb", a->memory_mb, "Resident tile memory budget (MiB)")
      ->capture_default_str();
  cmd->add_option("--budget", a->budget, "Point budget (0: none)")->capture_default_str();
  cmd->add_option("--splat-budget", a->splat_budget,
                  "Splat tilesets: the most splats drawn a frame (0: none)")
      ->capture_default_str();
  cmd->add_option("--backend", a->backend, "WebGPU implementation: dawn or wgpu")
      ->check(CLI::IsMember({"dawn", "wgpu", "wgpu-native"}));
  cmd->add_option("--json", a->json, "Write the results (and every frame's times) as JSON");
  add_flight_duration_option(cmd, a->duration);
  cmd->add_option("--samples", a->samples,
                  "Write a CSV row every --sample-seconds: RSS, resident tile bytes, GPU bytes, "
                  "loads, evictions, errors");
  cmd->add_option("--sample-seconds", a->sample_seconds,
                  "Seconds between --samples rows (0: every frame)")
      ->check(CLI::Range(0.0, 3600.0))
      ->capture_default_str();
  add_frame_mode_options(cmd, a->mode);
  cmd->callback([a] {
    check_camera_path(a->path);
    run_stream_bench(*a);
  });
}

}  // namespace stipple::app
