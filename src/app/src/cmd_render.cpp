// `stipple render`: headless rendering of LAS/LAZ/COPC files (or the built-in scene) to PNG:
// scene::render_image (libstipple) draws the image, this writes it and the summary.
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "stipple/app/commands.hpp"
#include "stipple/app/point_options.hpp"
#include "stipple/app/scene.hpp"
#include "stipple/core/atomic_file.hpp"
#include "stipple/core/log.hpp"
#include "stipple/core/stats.hpp"
#include "stipple/io/fetch.hpp"
#include "stipple/renderer/png.hpp"
#include "stipple/scene/render.hpp"

namespace stipple::app {
namespace {

struct RenderArgs : scene::RenderOptions {
  std::string output = "stipple.png";
  std::string stats;
  bool progressive = false;
  std::string progressive_first;          // empty: the output's name with "-first"
  uint64_t progressive_points = 1 << 18;  // the first image's sample
};

// The first image's file: given, else beside the output ("out.png" -> "out-first.png").
std::string first_image_path(const RenderArgs& args) {
  if (!args.progressive_first.empty()) return args.progressive_first;
  const std::filesystem::path out(args.output);
  return (out.parent_path() / (out.stem().string() + "-first" + out.extension().string())).string();
}

scene::RenderResult render(const RenderArgs& args) {
  if (!args.progressive) return scene::render_image(args);
  const auto start = std::chrono::steady_clock::now();
  return scene::render_progressive(
      args, args.progressive_points, [&](const scene::RenderResult& first) {
        const std::string path = first_image_path(args);
        gpu::write_png(path, first.image);
        std::printf(
            "first image: %llu points read across the input, written to %s in %.2f s\n",
            static_cast<unsigned long long>(first.stats.points_total), path.c_str(),
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
        std::fflush(stdout);
      });
}

void run_render(const RenderArgs& args) {
  const scene::RenderResult r = render(args);
  gpu::write_png(args.output, r.image);
  STIPPLE_INFO("wrote {} ({}x{})", args.output, r.image.width, r.image.height);
  const auto& stats = r.stats;
  const auto& description = r.adapter;
  if (!args.stats.empty()) {
    nlohmann::json j;
    j["backend"] = description.backend;
    j["adapter"] = description.device;
    j["graphics_api"] = description.graphics_api;
    j["points"] = stats.points_total;
    j["width"] = args.width;
    j["height"] = args.height;
    j["point_size_px"] = r.point_size;
    j["splats"] = r.splats;
    j["frames"] = args.frames;
    j["pipelined"] = args.pipelined;
    j["renderer"] = r.compute ? "compute" : "billboard";
    j["load_s"] = r.load_seconds;
    if (r.cache_built) {
      const pc::PointletBuildStats& b = r.cache_build;
      j["cache_build"] = {{"points", b.points},
                          {"runs", b.runs},
                          {"seconds", b.seconds},
                          {"read_seconds", b.read_seconds},
                          {"sort_seconds", b.sort_seconds},
                          {"merge_seconds", b.merge_seconds},
                          {"encode_seconds", b.encode_seconds},
                          {"write_seconds", b.write_seconds},
                          {"write_wait_seconds", b.write_wait_seconds},
                          {"run_bytes", b.run_bytes},
                          {"run_disk_bytes", b.run_disk_bytes},
                          {"run_read_seconds", b.run_read_seconds}};
    }
    j["passes"] = nlohmann::json::object();
    for (const auto& [name, ms] : stats.history) {
      j["passes"][name]["gpu_ms"] = ms;
      j["passes"][name]["gpu_ms_median"] = median(ms);
    }
    j["frame_gpu_ms_median"] = median(stats.gpu_ms);
    j["transient_textures_created"] = r.transient_textures_created;
    j["transient_buffers_created"] = r.transient_buffers_created;
    j["frame_wall_ms"] = stats.wall_ms;
    j["frame_wall_ms_median"] = median(stats.wall_ms);
    j["gpu_timing"] = !stats.gpu_ms.empty();
    auto points_ms = stats.history.find(r.compute ? "raster-depth" : "points");
    if (!stats.gpu_ms.empty() && median(stats.gpu_ms) > 0 && points_ms != stats.history.end())
      j["points_per_second"] = double(stats.points_total) / (median(points_ms->second) * 1e-3);
    write_file_atomically(args.stats, j.dump(2) + "\n");
  }
  if (args.frames > 1)
    std::printf("%u frames: GPU %.3f ms, wall %.3f ms per frame (median)\n", args.frames,
                median(stats.gpu_ms), median(stats.wall_ms));
  // The count is what the last frame drew: a frame that drew none says so.
  const std::string drawn = stats.points_drawn != stats.points_total
                                ? fmt::format("{} of {}", stats.points_drawn, stats.points_total)
                                : std::to_string(stats.points_total);
  if (stats.points_drawn == 0 && stats.points_total > 0)
    STIPPLE_WARN("no points were drawn: the image shows the background only");
  const std::string splats = r.splats > 0 ? fmt::format(" and {} splats", r.splats) : "";
  std::printf("rendered %s points%s (%s colour, %.1f px) with %s on %s to %s (%ux%u) in %.2f s\n",
              drawn.c_str(), splats.c_str(), r.color_source.c_str(), double(r.point_size),
              description.backend.c_str(), description.device.c_str(), args.output.c_str(),
              args.width, args.height, r.seconds);
}

}  // namespace

void add_render_command(CLI::App& cli) {
  auto args = std::make_shared<RenderArgs>();
  auto* cmd =
      cli.add_subcommand("render",
                         "Render point clouds (LAS/LAZ/COPC) headless to a PNG; with no input, the "
                         "built-in procedural scene");
  cmd->add_option(
         "inputs", args->scene.inputs,
         "Input files (.las, .laz, .copc.laz) and folders of LAS/LAZ tiles (one cloud), or one "
         "3D Tiles tileset.json, Potree "
         "metadata.json or cloud.js, or EPT ept.json path or URL; Gaussian splat files (.ply, "
         ".splat, .spz, .ksplat, .sog) drawn with them or alone")
      ->check([](const std::string& in) {
        return io::is_url(in) ? std::string() : CLI::ExistingPath(in);
      });
  cmd->add_option("-o,--output", args->output, "Output PNG")->capture_default_str();
  cmd->add_option("--width", args->width, "Image width in pixels")
      ->check(CLI::Range(1u, 16384u))
      ->capture_default_str();
  cmd->add_option("--height", args->height, "Image height in pixels")
      ->check(CLI::Range(1u, 16384u))
      ->capture_default_str();
  cmd->add_option("--camera", args->camera,
                  "Camera as 'eye_x,eye_y,eye_z,target_x,target_y,target_z' in the data's "
                  "coordinates (Z up; local ENU metres for lon/lat data); default frames the data");
  cmd->add_option("--azimuth", args->azimuth,
                  "Auto-framing: view azimuth in degrees (0 = from south)")
      ->capture_default_str();
  cmd->add_option("--elevation", args->elevation, "Auto-framing: view elevation in degrees")
      ->check(CLI::Range(-89.0, 89.0))
      ->capture_default_str();
  cmd->add_option("--fov", args->fov, "Vertical field of view in degrees")
      ->check(CLI::Range(1.0, 170.0))
      ->capture_default_str();
  cmd->add_option("--backend", args->backend,
                  "WebGPU implementation: dawn or wgpu "
                  "(default: $STIPPLE_BACKEND, else wgpu)")
      ->check(CLI::IsMember({"dawn", "wgpu", "wgpu-native"}));
  add_point_render_options(cmd, args->scene.render);
  cmd->add_option("--scene-points", args->scene.scene_points, "Built-in scene: number of points")
      ->check(CLI::Range(uint64_t(1), uint64_t(1) << 32))
      ->capture_default_str();
  cmd->add_option("--seed", args->scene.seed, "Built-in scene: random seed")->capture_default_str();
  cmd->add_option("--frames", args->frames, "Render this many frames (timing; the last is saved)")
      ->check(CLI::Range(1u, 100000u))
      ->capture_default_str();
  cmd->add_option("--stats", args->stats,
                  "Write timings (GPU ms per pass from timestamp queries, "
                  "wall ms per frame) as JSON");
  cmd->add_option("--dump-graph", args->dump_graph,
                  "Write the frame's render graph as Graphviz DOT (culled passes dashed)");
  cmd->add_flag("--progressive", args->progressive,
                "LAS/LAZ: write a first image at once, drawn from a sample read across the whole "
                "input (LAS: records at a stride; LAZ: the first points of every chunk) while "
                "the pointlet cache builds (virtualized path), then the full image to --output");
  cmd->add_option("--progressive-first", args->progressive_first,
                  "--progressive: the first image's PNG (default: the output's name with "
                  "'-first', e.g. stipple-first.png)");
  cmd->add_option("--progressive-points", args->progressive_points,
                  "--progressive: about how many points the first image reads")
      ->check(CLI::Range(uint64_t(1), uint64_t(1) << 32))
      ->capture_default_str();
  cmd->add_flag("--pipelined", args->pipelined,
                "Run the render world on its own thread (the same images as without)");
  add_scene_options(cmd, args->scene);
  cmd->add_option("--max-frames", args->max_frames,
                  "Tilesets: write the image after this many frames even if tiles are still "
                  "streaming")
      ->check(CLI::Range(uint64_t(1), uint64_t(1) << 32))
      ->capture_default_str();
  cmd->callback([args] { run_render(*args); });
}

}  // namespace stipple::app
