#include "stipple/scene/scene.hpp"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <utility>

#include <fmt/format.h>

#include "stipple/core/error.hpp"
#include "stipple/core/log.hpp"
#include "stipple/core/memory.hpp"
#include "stipple/engine/engine.hpp"
#include "stipple/io/copc.hpp"
#include "stipple/io/ept.hpp"
#include "stipple/io/fetch.hpp"
#include "stipple/io/las.hpp"
#include "stipple/io/potree.hpp"
#include "stipple/pointcloud/compute_raster.hpp"
#include "stipple/pointcloud/point_cloud_plugin.hpp"
#include "stipple/pointcloud/scene.hpp"
#include "stipple/pointcloud/virtual_cloud.hpp"
#include "stipple/renderer/gpu.hpp"
#include "stipple/tiles3d/render_load.hpp"
#include "stipple/tiles3d/tileset_plugin.hpp"

namespace stipple::scene {

bool is_tileset_scene(const SceneOptions& options) {
  return options.inputs.size() == 1 && tiles3d::is_tileset_input(options.inputs[0]);
}

double max_sse_for(const SceneOptions& options) {
  if (options.max_sse > 0) return options.max_sse;
  // COPC, Potree and EPT nodes' error is their point spacing: refine down to 2 px.
  return is_tileset_scene(options) &&
                 (io::is_copc_input(options.inputs[0]) || io::is_potree_input(options.inputs[0]) ||
                  io::is_ept_input(options.inputs[0]))
             ? 2.0
             : 16.0;
}

namespace {

uint64_t host_budget(const SceneOptions& options) {
  if (!options.host_memory.empty()) return parse_size(options.host_memory);
  const long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGE_SIZE);
  return pages > 0 && page > 0 ? uint64_t(pages) * uint64_t(page) / 4 : uint64_t(4) << 30;
}

}  // namespace

void apply_filters(SceneOptions& options) {
  options.render.filter = make_filter(options.filters);
  options.render.clip = make_region(options.filters);
}

bool use_virtual_path(const SceneOptions& options, std::string* reason) {
  if (options.inputs.empty() || is_tileset_scene(options)) return false;
  // GPS-time and point-source filters are drawn by the billboard path: the in-memory path keeps
  // them possible.
  if (options.render.filter.needs_extras() && !options.force_virtual) return false;
  if (options.force_virtual) {
    if (reason) *reason = "--virtual";
    return true;
  }
  // The in-memory path holds about 40 bytes a point (chunks, upload, batches).
  uint64_t points = 0;
  for (const auto& in : options.inputs) points += io::read_las_header(in).point_count;
  const uint64_t need = points * 40, budget = host_budget(options);
  if (need <= budget) return false;
  if (reason)
    *reason = fmt::format(
        "{} points need about {:.1f} GiB in memory, over the host budget of "
        "{:.1f} GiB (--host-memory)",
        points, double(need) / (1 << 30), double(budget) / (1 << 30));
  return true;
}

const char* renderer_name(Renderer renderer) {
  switch (renderer) {
    case Renderer::Compute:
      return "compute";
    case Renderer::Billboard:
      return "billboard";
    default:
      return "auto";
  }
}

Renderer resolve_renderer(const SceneOptions& options, const gpu::Context& ctx,
                          std::string* reason) {
  auto say = [&](Renderer r, std::string why) {
    if (reason) *reason = std::move(why);
    return r;
  };
  // GPS-time and point-source filters read the billboard path's per-point extras; the compute
  // rasterizer's batches hold positions, colours and the attribute word only.
  const bool extras = options.render.filter.needs_extras();
  if (extras && (options.renderer == Renderer::Compute || options.force_virtual))
    fail(
        "--gps-time-range and --point-source-range are drawn by the billboard renderer: leave "
        "out --renderer compute and --virtual");
  if (options.renderer != Renderer::Auto) return say(options.renderer, "--renderer");
  if (extras) return say(Renderer::Billboard, "auto: GPS-time and point-source filters");
  if (use_virtual_path(options))
    return say(Renderer::Compute, "auto: the virtualized path draws with it");
  // Points known up front: LAS/LAZ headers, a COPC header, the built-in scene; a 3D Tiles
  // tileset's size is not.
  constexpr uint64_t kComputeFrom = 10'000'000;
  uint64_t points = 0;
  if (options.points) {
    points = options.points->point_count;
  } else if (options.inputs.empty()) {
    points = options.scene_points;
  } else if (is_tileset_scene(options)) {
    if (!io::is_copc_input(options.inputs[0])) {
      // A tileset's size is not known up front (the tiles are read as the view refines): what
      // can be drawn at once is what the memory budget holds.
      points = (options.memory_mb << 20) / pc::kRasterPointBytes;
      if (points >= kComputeFrom)
        return say(Renderer::Compute,
                   fmt::format("auto: up to {} points streamed in --memory-mb {}, on {}", points,
                               options.memory_mb, ctx.description.adapter_type));
      return say(Renderer::Billboard,
                 fmt::format("auto: up to {} points streamed in --memory-mb {}, under {}", points,
                             options.memory_mb, kComputeFrom));
    }
    // The header and VLRs only: the plugin opens the hierarchy (and reads the root node).
    const io::Fetcher fetcher = [](const std::string& uri) { return io::fetch(uri); };
    points = io::open_copc(options.inputs[0], fetcher)->header.point_count;
  } else {
    for (const auto& in : options.inputs) points += io::read_las_header(in).point_count;
  }
  if (points >= kComputeFrom)
    return say(Renderer::Compute,
               fmt::format("auto: {} points on {}", points, ctx.description.adapter_type));
  return say(
      Renderer::Billboard,
      fmt::format("auto: {} points, under {}: point sizes above one pixel", points, kComputeFrom));
}

std::vector<double> parse_numbers(const std::string& text, size_t expected, const char* what) {
  std::vector<double> values;
  size_t start = 0;
  while (start <= text.size()) {
    size_t comma = text.find(',', start);
    std::string part =
        text.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    try {
      size_t used = 0;
      values.push_back(std::stod(part, &used));
      if (used != part.size()) throw std::invalid_argument(part);
    } catch (const std::exception&) {
      fail("{} '{}': '{}' is not a number", what, text, part);
    }
    if (!std::isfinite(values.back())) fail("{} '{}': values must be finite", what, text);
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  if (values.size() != expected)
    fail("{} '{}': expected {} comma-separated numbers, got {}", what, text, expected,
         values.size());
  return values;
}

Camera frame_scene(Registry& main, uint32_t width, uint32_t height, double azimuth,
                   double elevation, double fov) {
  ViewFit fit(width, height, azimuth, elevation, fov);
  main.view<pc::PointCloudData>().each([&](const pc::PointCloudData& data) {
    if (data.cloud) pc::fit_cloud(fit, *data.cloud);
  });
  if (fit.empty())
    if (const auto* handle = main.try_resource<pc::VirtualCloudHandle>())
      pc::fit_virtual_cloud(fit, *handle);
  if (fit.empty())
    if (const auto* stream = main.try_resource<tiles3d::TilesetStream>())
      fit.add_corners(stream->world_bounds);
  if (fit.empty()) fit.add_corners(main.resource<pc::SceneInfo>().world_bounds);
  return fit.camera();
}

Camera scene_camera(Registry& main, const std::string& text, uint32_t width, uint32_t height,
                    double azimuth, double elevation, double fov) {
  if (text.empty()) return frame_scene(main, width, height, azimuth, elevation, fov);
  const std::vector<double> v = parse_numbers(text, 6, "--camera");
  Camera camera;
  camera.fov_y = glm::radians(fov);
  const glm::dvec3 eye = z_up_to_y_up({v[0], v[1], v[2]});
  const glm::dvec3 target = z_up_to_y_up({v[3], v[4], v[5]});
  if (glm::length(target - eye) <= 0.0) fail("--camera: eye and target are the same point");
  camera.look_at(eye, target);
  camera.near_plane = std::max(glm::length(target - eye) * 1e-4, 1e-3);
  return camera;
}

void add_scene_plugin(Engine& engine, const SceneOptions& options) {
  const bool compute = options.renderer == Renderer::Compute;
  if (is_tileset_scene(options)) {
    // 3D Tiles: streamed frame by frame with the camera (out of core).
    tiles3d::TilesetPlugin tiles;
    tiles.compute = compute;
    tiles.raster.hqs = options.hqs;
    tiles.raster.fill_radius = options.fill_radius < 0 ? 0u : uint32_t(options.fill_radius);
    tiles.raster.occlusion_beta = options.occlusion_beta;
    tiles.uri = options.inputs[0];
    tiles.streamer.traversal.max_sse = max_sse_for(options);
    tiles.streamer.traversal.memory_budget = options.memory_mb << 20;
    tiles.streamer.traversal.point_budget = options.budget;
    tiles.render = options.render;
    engine.add_plugin(std::move(tiles));
    return;
  }
  std::string reason;
  if (use_virtual_path(options, &reason)) {
    std::printf("drawing from a pointlet cache (%s)%s\n", reason.c_str(),
                compute ? "" : "; the virtualized path draws with the compute rasterizer");
    pc::VirtualPointCloudPlugin v;
    v.options.files.assign(options.inputs.begin(), options.inputs.end());
    v.options.cache_dir = options.cache_dir;
    v.options.build.pointlets = options.pointlets;
    v.options.build.memory_budget = std::min<uint64_t>(host_budget(options) / 2, uint64_t(4) << 30);
    // The host budget is the process's: the loaded points get what the two mapped staging
    // slots leave, and once the first frame has run, at most what the rest of the process
    // (libraries, driver, tables, and the GPU buffers on a software GPU) leaves of it.
    const uint64_t budget = host_budget(options);
    v.options.staging_bytes =
        std::clamp<uint64_t>(budget / 16, uint64_t(1) << 20, uint64_t(64) << 20);
    v.options.host_budget =
        budget > 4 * v.options.staging_bytes ? budget - 2 * v.options.staging_bytes : budget / 2;
    v.options.process_budget = budget;
    if (!options.gpu_memory.empty()) v.options.gpu_budget = parse_size(options.gpu_memory);
    v.options.bucket = options.bucket;
    v.options.hqs = options.hqs;
    v.options.fill_radius = options.fill_radius < 0 ? 1u : uint32_t(options.fill_radius);
    v.options.occlusion_beta = options.occlusion_beta;
    v.render = options.render;
    engine.add_plugin(std::move(v));
    const auto& c = engine.main().resource<pc::VirtualCloudCache>();
    if (c.built)
      std::printf("built %s: %llu points in %llu pointlets of %llu in %.2f s\n", c.path.c_str(),
                  static_cast<unsigned long long>(c.points),
                  static_cast<unsigned long long>(c.pointlets),
                  static_cast<unsigned long long>(c.pointlet_points), c.build.seconds);
    else
      std::printf("reused %s (the input is unchanged)\n", c.path.c_str());
    return;
  }
  if (options.points && !options.inputs.empty())
    fail("points in memory and input files cannot be drawn together");
  pc::PointCloudPlugin points;
  points.inputs.files.assign(options.inputs.begin(), options.inputs.end());
  points.inputs.points = options.points;
  points.inputs.scene.point_count = options.scene_points;
  points.inputs.scene.seed = options.seed;
  points.inputs.chunk_points = options.chunk_points;
  points.inputs.keep_extras = options.keep_extras || options.render.filter.needs_extras();
  points.settings.render = options.render;
  points.settings.budget = options.budget;
  points.settings.compute = compute;
  points.settings.hqs = options.hqs;
  points.settings.fill_radius = options.fill_radius < 0 ? 0u : uint32_t(options.fill_radius);
  points.settings.occlusion_beta = options.occlusion_beta;
  engine.add_plugin(std::move(points));
}

}  // namespace stipple::scene
