// `stipple bench virtual`: the virtualized renderer (seed 002) over the seed's camera path, an
// orbit around the cloud's centre while the vertical field of view zooms in and out (section
// IV-B, Table II and Figs. 12-15), for one or more point buckets B (Fig. 14). Every frame is
// drawn headless at the given size and timed; the summary is Table II's FPS statistics, the
// five GPU stages of Fig. 15, the memory in use, and optionally the PSNR of settled views
// against the full-detail image, with and without hole filling (Figs. 16-17).
//
// A frame's time is the wall time of one engine update. By default that is the CPU work of the
// frame (LoD and its readback, planning, staging), its GPU work and the read of its timestamps,
// one after the other (no overlap of frames, so FPS is a lower bound of what a pipelined viewer
// reaches). With --pipelined the render world runs on its own thread (seed 000's pipelined mode:
// the main world builds frame N+1 while N is drawn) and frames do not wait for the GPU: their
// timestamps are read back a few frames later, and at most two frames are unfinished on the GPU
// (as a swapchain would allow); --no-gpu-wait does the latter without the render thread. Loads
// run on the worker pool meanwhile, as in an interactive session: frames do not wait for them.
// The selection (what to draw, load and transfer) runs on its own thread as in the viewer, the
// frames drawing the last one until the next is done; --sync-selection makes it in the frame.
// The path runs by frame (frame f of N at f / N), so faster frames fly it faster in wall time;
// with --duration it runs by the clock, and frames that outrun the selection draw less of what
// the view wants (the drawn points a frame say how much).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
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
#include "stipple/math/camera.hpp"
#include "stipple/pointcloud/compute_raster.hpp"
#include "stipple/pointcloud/scene.hpp"
#include "stipple/pointcloud/virtual_cloud.hpp"

namespace stipple::app {
namespace {

struct VirtualBenchArgs {
  std::vector<std::string> inputs;
  std::vector<uint64_t> buckets = {25'000'000};
  uint32_t width = 1920, height = 1080;
  uint32_t frames = 600;
  CameraPath path;
  uint32_t fill_radius = 1;
  float occlusion_beta = 0.0f;
  uint32_t psnr_views = 0;
  std::string cache_dir, host_memory, gpu_memory, backend, json;
  uint64_t pointlets = pc::kDefaultPointlets;
  FrameMode mode;
  bool sync_selection = false;
  double duration = 0;  // seconds: the path by the clock; 0: by frame
};

std::unique_ptr<Engine> make_engine(const VirtualBenchArgs& a, uint64_t bucket, uint32_t fill) {
  auto engine = std::make_unique<Engine>();
  add_engine_core(*engine, bench_engine_core(a.backend, a.mode));
  SceneOptions scene;
  scene.inputs = a.inputs;
  scene.force_virtual = true;
  scene.cache_dir = a.cache_dir;
  scene.pointlets = a.pointlets;
  scene.host_memory = a.host_memory;
  scene.gpu_memory = a.gpu_memory;
  scene.bucket = bucket;
  scene.fill_radius = int(fill);
  scene.occlusion_beta = a.occlusion_beta;
  scene.async_selection = !a.sync_selection;
  add_scene_plugin(*engine, plan_scene(scene, *engine->render().resource<GpuContext>()));
  engine->add_plugin(HeadlessTargetPlugin{a.width, a.height, "", 0});
  return engine;
}

struct FlightResult {
  uint64_t bucket = 0;
  std::vector<double> wall_ms, gpu_ms;
  std::vector<uint64_t> drawn;
  std::array<double, 5> stage_sum{};
  double select_ms = 0, lod_ms = 0, update_ms = 0, residency_ms = 0, wait_ms = 0,
         write_ms = 0;                   // CPU, summed over frames
  double select_cpu_ms = 0;              // the selection's thread CPU time, summed
  double main_ms = 0;                    // CPU of the main world's stages, summed
  std::array<double, 5> render_ms{};     // CPU of each render stage, summed
  uint64_t new_points = 0, touched = 0;  // summed over selections
  uint64_t selections = 0;
  double async_select_ms = 0;  // summed over selections made on their own thread
  uint64_t peak_host = 0, peak_gpu = 0, staging = 0, points = 0;
  uint64_t peak_process = 0, peak_heap_free = 0, host_budget = 0;
  double load_s = 0, trim_ms = 0;
};

FlightResult fly(const VirtualBenchArgs& a, uint64_t bucket) {
  FlightResult out;
  out.bucket = bucket;
  auto start = std::chrono::steady_clock::now();
  auto engine = make_engine(a, bucket, a.fill_radius);
  out.load_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  Registry& main = engine->main();
  const Aabb world = main.resource<pc::SceneInfo>().world_bounds;
  out.points = main.resource<pc::SceneInfo>().points;
  const double aspect = double(a.width) / a.height;
  const Entity camera = main.create();
  main.emplace<Camera>(camera, path_camera(a.path, world, 0.0, aspect));
  Registry& render = engine->render();
  Progress progress(fmt::format("B = {:.1f} M", bucket / 1e6), a.frames, "frames");
  uint64_t selections = 0;
  // Each frame's statistics as the main world sees them after the sync point (those of the
  // frame before: in pipelined mode the render world is drawing this one meanwhile); the last
  // frame's are taken once the render world is idle.
  auto account = [&](const pc::VirtualCloudStats& vs, uint64_t drawn) {
    out.drawn.push_back(drawn);
    for (size_t s = 0; s < 5; ++s) out.stage_sum[s] += vs.stage_ms[s];
    out.select_ms += vs.select_ms;
    out.select_cpu_ms += vs.select_cpu_ms;
    if (vs.selections != selections) {  // this frame made a selection
      out.lod_ms += vs.lod_ms;
      out.update_ms += vs.upload_ms;
      out.residency_ms += vs.residency_ms;
      out.wait_ms += vs.staging_wait_ms;
      out.write_ms += vs.fresh_write_ms;
      out.new_points += vs.new_points;
      out.touched += vs.touched_pointlets;
      out.async_select_ms += vs.async_select_ms;
      out.selections += vs.selections - selections;
      selections = vs.selections;
    }
    out.peak_host = std::max(out.peak_host, vs.host_bytes);
    out.peak_gpu = std::max(out.peak_gpu, vs.gpu_bytes);
    out.peak_process = std::max(out.peak_process, vs.process_bytes);
    out.peak_heap_free = std::max(out.peak_heap_free, vs.heap_free_bytes);
    out.host_budget = vs.host_budget;
    out.trim_ms = vs.trim_ms;
    out.staging = vs.staging_bytes;
    if (vs.bucket) out.bucket = vs.bucket;  // lowered when it does not fit --gpu-memory
  };
  const auto flight_start = std::chrono::steady_clock::now();
  auto flown = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - flight_start).count();
  };
  for (uint32_t f = 0; f < a.frames; ++f) {
    // With --duration the camera moves by the clock, at the same speed however fast the
    // frames come, so that builds and modes whose frames take different times fly the same
    // views in the same time (and the frames that draw a selection still being made count).
    const std::optional<double> along = flight_along(a.duration, flown(), f, a.frames);
    if (!along) break;
    main.get<Camera>(camera) = path_camera(a.path, world, *along, aspect);
    const auto t0 = std::chrono::steady_clock::now();
    engine->update();
    out.wall_ms.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    if (f > 0)
      account(main.resource<pc::VirtualCloudStats>(),
              main.resource<RenderStatsSnapshot>().points_drawn);
    progress.advance(1);
  }
  drain_pass_times(*engine);  // waits for the render world and every frame's timestamps
  account(render.resource<pc::VirtualCloudStats>(), render.resource<RenderStats>().points_drawn);
  out.gpu_ms = render.resource<RenderStats>().gpu_ms;
  out.main_ms = engine->main_cpu_ms();
  out.render_ms = engine->render_cpu_ms();
  progress.finish();
  engine->shutdown();
  return out;
}

// Settled images of `views`: frames run until nothing loads and the transfer is complete.
std::vector<gpu::Image> settled_images(const VirtualBenchArgs& a, uint64_t bucket, uint32_t fill,
                                       const std::vector<Camera>& views) {
  auto engine = make_engine(a, bucket, fill);
  Registry& main = engine->main();
  Registry& render = engine->render();
  const Entity camera = main.create();
  main.emplace<Camera>(camera, views.front());
  std::vector<gpu::Image> images;
  auto latest = std::make_shared<gpu::Image>();
  for (const Camera& view : views) {
    main.get<Camera>(camera) = view;
    for (int i = 0; i < 5000; ++i) {
      engine->update();
      engine->wait_for_render();  // pipelined: the render world's stats are read when it idles
      const auto& s = render.resource<pc::VirtualCloudStats>();
      if (s.settled && s.selections > 0) break;
      pc::wait_for_virtual_loads(main.resource<pc::VirtualCloudHandle>(), 0.05);
    }
    render.insert_resource(
        FrameCapture{[latest](uint64_t, const gpu::Image& image) { *latest = image; }});
    engine->update();
    render.insert_resource(FrameCapture{});
    images.push_back(*latest);
  }
  engine->shutdown();
  return images;
}

double psnr(const gpu::Image& a, const gpu::Image& b) {
  if (a.width != b.width || a.height != b.height || a.rgba.size() != b.rgba.size())
    fail("PSNR of images of different sizes");
  double se = 0;
  uint64_t n = 0;
  for (size_t i = 0; i < a.rgba.size(); i += 4)
    for (int c = 0; c < 3; ++c) {
      const double d = double(a.rgba[i + c]) - double(b.rgba[i + c]);
      se += d * d;
      ++n;
    }
  const double mse = se / double(std::max<uint64_t>(n, 1));
  return mse == 0 ? std::numeric_limits<double>::infinity()
                  : 10.0 * std::log10(255.0 * 255.0 / mse);
}

void run_virtual_bench(const VirtualBenchArgs& a) {
  nlohmann::json j;
  j["inputs"] = a.inputs;
  j["width"] = a.width;
  j["height"] = a.height;
  j["frames"] = a.frames;
  j["fov_deg"] = {a.path.fov_min, a.path.fov_max};
  j["fill_radius"] = a.fill_radius;
  j["occlusion_beta"] = a.occlusion_beta;
  j["pipelined"] = a.mode.pipelined;
  j["gpu_wait"] = a.mode.waits_for_gpu();
  j["async_selection"] = !a.sync_selection;
  j["duration_s"] = a.duration;
  j["runs"] = nlohmann::json::array();
  std::printf("%10s %8s %8s %8s %8s %8s %8s %9s %9s %9s %9s\n", "B", "FPS avg", "min", "max",
              "1% low", "0.1% low", "GPU FPS", "drawn M", "host MiB", "GPU MiB", "RSS MiB");
  uint64_t points = 0;
  for (uint64_t bucket : a.buckets) {
    FlightResult r = fly(a, bucket);
    points = r.points;
    const double total_ms = std::accumulate(r.wall_ms.begin(), r.wall_ms.end(), 0.0);
    const double avg = total_ms > 0 ? 1000.0 * r.wall_ms.size() / total_ms : 0;
    const double gpu_total = std::accumulate(r.gpu_ms.begin(), r.gpu_ms.end(), 0.0);
    const double gpu_fps = gpu_total > 0 ? 1000.0 * r.gpu_ms.size() / gpu_total : 0;
    const auto [fast, slow] = std::minmax_element(r.wall_ms.begin(), r.wall_ms.end());
    const double max_fps = *fast > 0 ? 1000.0 / *fast : 0, min_fps = *slow > 0 ? 1000.0 / *slow : 0;
    const double drawn =
        std::accumulate(r.drawn.begin(), r.drawn.end(), 0.0) / std::max<size_t>(1, r.drawn.size());
    const uint64_t rss = peak_resident_bytes();
    std::printf("%10.2fM %8.1f %8.1f %8.1f %8.1f %8.1f %8.1f %9.2f %9.1f %9.1f %9.1f\n",
                r.bucket / 1e6, avg, min_fps, max_fps, low_fps(r.wall_ms, 0.01),
                low_fps(r.wall_ms, 0.001), gpu_fps, drawn / 1e6, r.peak_host / 1048576.0,
                r.peak_gpu / 1048576.0, rss / 1048576.0);
    nlohmann::json run;
    run["bucket"] = r.bucket;
    run["bucket_asked"] = bucket;
    run["points"] = r.points;
    run["fps"] = {{"average", avg},
                  {"min", min_fps},
                  {"max", max_fps},
                  {"low_1pct", low_fps(r.wall_ms, 0.01)},
                  {"low_0_1pct", low_fps(r.wall_ms, 0.001)},
                  {"gpu_average", gpu_fps}};
    run["frame_wall_ms"] = r.wall_ms;
    run["frame_gpu_ms"] = r.gpu_ms;
    run["points_drawn_mean"] = drawn;
    nlohmann::json stages;
    for (size_t s = 0; s < 5; ++s)
      stages[std::string(pc::kStageNames[s])] =
          r.stage_sum[s] / std::max<size_t>(1, r.wall_ms.size());
    run["stage_gpu_ms_mean"] = stages;
    const double frames = double(std::max<size_t>(1, r.wall_ms.size()));
    run["cpu_ms_mean"] = {{"selection", r.select_ms / frames},
                          {"selection_thread_cpu", r.select_cpu_ms / frames},
                          {"lod", r.lod_ms / frames},
                          {"residency", r.residency_ms / frames},
                          {"store_update", r.update_ms / frames},
                          {"staging_wait", r.wait_ms / frames},
                          {"new_points_write", r.write_ms / frames},
                          {"main_stages", r.main_ms / frames},
                          {"render_prepare", r.render_ms[0] / frames},
                          {"render_queue", r.render_ms[1] / frames},
                          {"render_predraw", r.render_ms[2] / frames},
                          {"render_draw", r.render_ms[3] / frames},
                          {"render_postdraw", r.render_ms[4] / frames}};
    run["new_points_mean"] = double(r.new_points) / frames;
    run["selections"] = r.selections;
    run["async_selection_ms_mean"] =
        r.async_select_ms / double(std::max<uint64_t>(1, r.selections));
    run["touched_pointlets_mean"] = double(r.touched) / frames;
    run["peak_host_points_bytes"] = r.peak_host;
    run["peak_gpu_bytes"] = r.peak_gpu;
    run["staging_bytes"] = r.staging;
    run["peak_rss_bytes"] = rss;
    run["peak_process_bytes_at_selection"] = r.peak_process;
    run["peak_heap_free_bytes"] = r.peak_heap_free;
    run["points_budget_bytes_last"] = r.host_budget;
    run["malloc_trim_ms_total"] = r.trim_ms;
    run["open_s"] = r.load_s;
    j["runs"].push_back(run);
    std::printf("           stages (GPU ms, mean a frame):");
    for (size_t s = 0; s < 5; ++s)
      std::printf(" %s %.3f", std::string(pc::kStageNames[s]).c_str(),
                  r.stage_sum[s] / std::max<size_t>(1, r.wall_ms.size()));
    const double frames_n = double(std::max<size_t>(1, r.wall_ms.size()));
    std::printf(
        "\n           CPU ms a frame: selection %.3f (LoD %.3f, residency %.3f, store update "
        "%.3f: staging wait %.3f, new points %.3f), whole frame %.3f\n",
        r.select_ms / frames_n, r.lod_ms / frames_n, r.residency_ms / frames_n,
        r.update_ms / frames_n, r.wait_ms / frames_n, r.write_ms / frames_n,
        std::accumulate(r.wall_ms.begin(), r.wall_ms.end(), 0.0) / frames_n);
    std::printf(
        "           %s, CPU ms a frame by stage: main %.3f | render Prepare %.3f, Queue %.3f, "
        "PreDraw %.3f, Draw %.3f, PostDraw %.3f; new points %.0f, pointlets touched %.0f a "
        "frame; selection as thread CPU time %.3f ms\n",
        a.mode.name(), r.main_ms / frames_n, r.render_ms[0] / frames_n, r.render_ms[1] / frames_n,
        r.render_ms[2] / frames_n, r.render_ms[3] / frames_n, r.render_ms[4] / frames_n,
        double(r.new_points) / frames_n, double(r.touched) / frames_n, r.select_cpu_ms / frames_n);
    if (!a.sync_selection)
      std::printf(
          "           selections on their own thread: %llu in %zu frames, %.3f ms each (wall); "
          "the frames drew the last one meanwhile\n",
          static_cast<unsigned long long>(r.selections), r.wall_ms.size(),
          r.async_select_ms / double(std::max<uint64_t>(1, r.selections)));
  }
  if (a.psnr_views > 0) {
    // Views spread over the path; the reference draws every point (B = n).
    const double aspect = double(a.width) / a.height;
    Aabb world;
    {
      auto probe = make_engine(a, 1, 0);
      world = probe->main().resource<pc::SceneInfo>().world_bounds;
      probe->shutdown();
    }
    std::vector<Camera> views;
    for (uint32_t v = 0; v < a.psnr_views; ++v)
      views.push_back(path_camera(a.path, world, (v + 0.5) / a.psnr_views, aspect));
    nlohmann::json pj = nlohmann::json::array();
    for (uint32_t fill : {0u, a.fill_radius}) {
      auto reference = settled_images(a, points, fill, views);
      for (uint64_t bucket : a.buckets) {
        auto images = settled_images(a, bucket, fill, views);
        std::vector<double> values;
        for (size_t v = 0; v < views.size(); ++v) values.push_back(psnr(images[v], reference[v]));
        const double mean = std::accumulate(values.begin(), values.end(), 0.0) / values.size();
        std::printf("PSNR B = %.2f M, fill radius %u: mean %.2f dB (views:", bucket / 1e6, fill,
                    mean);
        for (double p : values) std::printf(" %.2f", p);
        std::printf(")\n");
        pj.push_back(
            {{"bucket", bucket}, {"fill_radius", fill}, {"psnr_db", values}, {"mean_db", mean}});
      }
      if (a.fill_radius == 0) break;
    }
    j["psnr"] = pj;
  }
  if (!a.json.empty()) write_file_atomically(a.json, j.dump(2) + "\n");
}

}  // namespace

void add_bench_virtual_command(CLI::App& bench) {
  auto a = std::make_shared<VirtualBenchArgs>();
  auto* cmd = bench.add_subcommand(
      "virtual",
      "Virtualized rendering over the seed's camera path (seed 002, Table II, Figs. 14-17)");
  cmd->add_option("inputs", a->inputs,
                  "LAS/LAZ/COPC files and folders of LAS/LAZ tiles (one cloud)")
      ->required();
  cmd->add_option("--bucket", a->buckets, "Point buckets B to run (several: the sweep of Fig. 14)")
      ->capture_default_str();
  cmd->add_option("--width", a->width, "Image width")->capture_default_str();
  cmd->add_option("--height", a->height, "Image height")->capture_default_str();
  cmd->add_option("--frames", a->frames, "Frames along the path")
      ->check(CLI::Range(1u, 1000000u))
      ->capture_default_str();
  add_camera_path_options(cmd, a->path);
  cmd->add_option("--fill-radius", a->fill_radius, "Hole filling radius (0: off)")
      ->check(CLI::Range(0, 8))
      ->capture_default_str();
  cmd->add_option("--occlusion-beta", a->occlusion_beta, "Occlusion check threshold (0: off)")
      ->check(CLI::Range(0.0f, 1.5f))
      ->capture_default_str();
  cmd->add_option("--psnr-views", a->psnr_views,
                  "Also compare this many settled views with the full-detail image (B = every "
                  "point), with and without hole filling");
  cmd->add_option("--pointlets", a->pointlets, "m of the pointlet cache")->capture_default_str();
  cmd->add_option("--cache", a->cache_dir, "Folder of the pointlet cache");
  cmd->add_option("--host-memory", a->host_memory, "Host memory budget, e.g. 4G");
  cmd->add_option("--gpu-memory", a->gpu_memory, "Device memory budget for the points, e.g. 4G");
  cmd->add_option("--backend", a->backend, "WebGPU implementation: dawn or wgpu")
      ->check(CLI::IsMember({"dawn", "wgpu", "wgpu-native"}));
  add_frame_mode_options(cmd, a->mode);
  add_flight_duration_option(cmd, a->duration);
  cmd->add_flag("--sync-selection", a->sync_selection,
                "Make each selection in the frame that needs it (frames wait for it), instead "
                "of on its own thread while frames draw the last one (the viewer's way)");
  cmd->add_option("--json", a->json, "Write the results (and every frame's times) as JSON");
  cmd->callback([a] {
    check_camera_path(a->path);
    run_virtual_bench(*a);
  });
}

}  // namespace stipple::app
