// render_image: headless rendering composed from engine plugins (the engine's core plugins, the
// device and frame graph, the scene's plugin and an offscreen target), returning the last frame.
#include "stipple/scene/render.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <utility>

#include <fmt/format.h>

#include "stipple/core/error.hpp"
#include "stipple/core/log.hpp"
#include "stipple/engine/plugins.hpp"
#include "stipple/io/point_batch.hpp"
#include "stipple/math/camera.hpp"
#include "stipple/pointcloud/compute_raster.hpp"
#include "stipple/pointcloud/point_cloud_plugin.hpp"
#include "stipple/pointcloud/virtual_cloud.hpp"
#include "stipple/tiles3d/tileset_plugin.hpp"

namespace stipple::scene {

template <typename T>
T Column<T>::operator[](size_t i) const {
  T v;
  std::memcpy(&v, data + ptrdiff_t(i) * stride, sizeof(T));
  return v;
}
template struct Column<double>;
template struct Column<uint16_t>;
template struct Column<uint8_t>;

std::shared_ptr<const pc::PointCloud> points_from_columns(const PointColumns& p,
                                                          size_t chunk_points) {
  if (!p.x || !p.y || !p.z) fail("points need x, y and z");
  const bool rgb = p.red && p.green && p.blue;
  // The LAS reader's rule (las_reader.cpp): 8-bit RGB when the first 65536 points all fit.
  constexpr size_t kRgbProbePoints = 65536;
  int rgb_bits = 16;
  bool uniform = false;
  if (rgb && p.count > 0) {
    const size_t n = std::min(p.count, kRgbProbePoints);
    bool eight = true;
    uniform = true;
    for (size_t i = 0; i < n; ++i) {
      const uint16_t r = p.red[i], g = p.green[i], b = p.blue[i];
      eight = eight && r <= 255 && g <= 255 && b <= 255;
      uniform = uniform && r == p.red[0] && g == p.green[0] && b == p.blue[0];
    }
    rgb_bits = eight ? 8 : 16;
  }
  auto cloud = std::make_shared<pc::PointCloud>();
  io::PointBatch batch;
  constexpr size_t kBatch = 1 << 16;
  for (size_t start = 0; start < p.count; start += kBatch) {
    const size_t end = std::min(p.count, start + kBatch);
    batch.clear();
    for (size_t i = start; i < end; ++i) {
      const glm::dvec3 v(p.x[i], p.y[i], p.z[i]);
      if (!std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.z))
        fail("point {} is not finite ({}, {}, {})", i, v.x, v.y, v.z);
      batch.positions.push_back(v);
      if (p.intensity) batch.intensity.push_back(p.intensity[i]);
      if (p.classification) batch.classification.push_back(p.classification[i]);
      if (p.return_number) batch.return_number.push_back(p.return_number[i]);
      if (p.number_of_returns) batch.number_of_returns.push_back(p.number_of_returns[i]);
      if (rgb) batch.rgb.emplace_back(p.red[i], p.green[i], p.blue[i]);
    }
    // The attribute word reads return numbers and their count together.
    if (batch.return_number.empty() != batch.number_of_returns.empty()) {
      if (batch.return_number.empty()) batch.return_number.assign(batch.size(), 1);
      if (batch.number_of_returns.empty()) batch.number_of_returns.assign(batch.size(), 1);
    }
    pc::append_batch(*cloud, batch, rgb_bits, chunk_points);
  }
  cloud->attributes.rgb_uniform = cloud->attributes.has_rgb && uniform;
  pc::finish_cloud(*cloud);
  return cloud;
}

RenderResult render_image(const RenderOptions& args) {
  const auto start = std::chrono::steady_clock::now();
  RenderResult result;
  Engine engine;
  engine.add_plugins(TimePlugin{}, TransformPlugin{}, CameraPlugin{});
  if (args.pipelined) engine.add_plugin(PipelinedRenderingPlugin{});
  SceneOptions scene_options = args.scene;
  apply_filters(scene_options);
  // The virtualized path (inputs over the host budget, or --virtual) draws with the compute
  // rasterizer too.
  const bool virtualized = use_virtual_path(scene_options);
  GpuPlugin gpu;
  gpu.options.backend = args.backend;
  // Requested always: --renderer auto decides once the adapter is known.
  gpu.options.optional_features = pc::compute_raster_features();
  engine.add_plugin(std::move(gpu));
  std::string renderer_reason;
  scene_options.renderer =
      resolve_renderer(scene_options, *engine.render().resource<GpuContext>(), &renderer_reason);
  bool compute = scene_options.renderer == Renderer::Compute || virtualized;
  // Blending's form on the compute rasterizer is HQS: a tileset auto-drawn there keeps it.
  if (args.scene.renderer == Renderer::Auto && compute && is_tileset_scene(scene_options))
    scene_options.hqs = scene_options.hqs || scene_options.render.splat == pc::SplatMode::Blend;
  RenderGraphPlugin graph;
  graph.keep_history = true;
  graph.dump_graph = args.dump_graph;
  engine.add_plugin(std::move(graph));
  // 3D Tiles are streamed frame by frame with the camera; the image is kept once the streamer
  // is idle (everything the view selects is resident), or at max_frames.
  const bool tileset = is_tileset_scene(scene_options);
  add_scene_plugin(engine, scene_options);
  // The virtualized path loads what the view needs while frames run; the image is kept once
  // nothing is loading any more (or at max_frames).
  HeadlessTargetPlugin target{args.width, args.height, "", 0};
  if (!tileset && !virtualized) {
    target.frames = args.frames;
    target.capture = true;
  }
  engine.add_plugin(std::move(target));

  Registry& main = engine.main();
  const Camera camera = scene_camera(main, args.camera, args.width, args.height, args.azimuth,
                                     args.elevation, args.fov);
  main.emplace<Camera>(main.create(), camera);
  auto& settings = main.resource<pc::PointDrawSettings>();
  const bool sized_by_data = settings.render.point_size <= 0;
  size_t clouds = 0;
  main.view<pc::PointCloudData>().each([&](const pc::PointCloudData& data) {
    ++clouds;
    if (settings.render.point_size <= 0)
      settings.render.point_size = pc::auto_point_size(*data.cloud, camera, args.height);
  });
  // Auto: where the data's density gives 1-pixel points, the compute rasterizer draws the same
  // image (blending as HQS does) far faster (measured on lavapipe, 12M points: 134 ms against
  // 6953 ms a frame), on any adapter.
  if (args.scene.renderer == Renderer::Auto && !compute && !tileset && sized_by_data &&
      settings.render.point_size <= 1.0f && clouds > 0 &&
      !scene_options.render.filter.needs_extras()) {
    compute = true;
    settings.compute = true;
    settings.hqs = settings.render.splat == pc::SplatMode::Blend;
    renderer_reason = "auto: 1-pixel points";
  }
  if (!args.quiet)
    std::printf("renderer: %s (%s)\n", compute ? "compute" : "billboard", renderer_reason.c_str());
  if (tileset) {
    // Frames run while tiles stream in (waiting for a load between frames); once idle, the point
    // size is fitted to what is drawn (unless given), `frames` more frames run and the last is
    // kept.
    const bool auto_size = settings.render.point_size <= 0;
    if (auto_size) settings.render.point_size = 2.0f;
    engine.add_system(
        MainStage::Update,
        [settled = uint64_t(0), frames = uint64_t(args.frames), max_frames = args.max_frames,
         height = args.height, memory_mb = args.scene.memory_mb, max_sse = max_sse_for(args.scene),
         point_budget = args.scene.budget, auto_size, uri = scene_options.inputs[0],
         reframe = args.camera.empty(), args](Registry& r) mutable {
          auto& s = r.resource<tiles3d::TilesetStream>();
          const auto& stats = r.resource<tiles3d::TilesetStats>();
          bool capped = stats.frames >= max_frames;
          // The traversal keeps the selection within the memory budget (coarser tiles where the
          // view wants more), so the streamer goes idle in every case.
          if (!stats.idle && !capped) {
            s.streamer->wait_for_progress();
            return;
          }
          // Framed from the tileset's volume (which may be far larger than the data) until the
          // first tiles are in: then once from their points, and streamed again for that view.
          if (reframe && !capped && stats.drawn_points > 0) {
            reframe = false;
            ViewFit fit(args.width, args.height, args.azimuth, args.elevation, args.fov);
            tiles3d::fit_drawn_tiles(fit, s);
            r.view<Camera>().each([&](Camera& c) { c = fit.camera(); });
            return;
          }
          if (settled == 0 && !stats.idle)
            STIPPLE_WARN("--max-frames {} reached before the tileset was streamed", max_frames);
          if (settled == 0 && stats.budget_limited && stats.drawn_tiles == 0)
            STIPPLE_WARN(
                "--memory-mb {} is smaller than the coarsest tiles this view needs: "
                "nothing is drawn (raise --memory-mb)",
                memory_mb);
          else if (settled == 0 && stats.budget_limited)
            STIPPLE_WARN(
                "the view wants more than --memory-mb {}{} allow: drawn at a screen-space error "
                "of {:.1f} px instead of --max-sse {} (raise them for more detail)",
                memory_mb, point_budget ? fmt::format(" and --budget {}", point_budget) : "",
                stats.sse_threshold, max_sse);
          else if (settled == 0 && stats.drawn_points == 0) {
            // Content was read and none of it is points (meshes, an empty pnts): an input with
            // no points is an error, as for LAS. Nothing read: no tile is in view.
            if ((stats.loads_completed > 0 || stats.errors > 0) && stats.resident_points == 0)
              fail("{}: nothing to render: the tiles in view hold no points{}", uri,
                   s.first_problem.empty() ? "" : fmt::format(" ({})", s.first_problem));
            STIPPLE_WARN("{}: no tile with points is in view: the image shows the background only",
                         uri);
          }
          if (settled++ == 0 && auto_size && stats.drawn_points > 0) {
            Aabb drawn;
            for (uint32_t t : s.draw)
              for (const auto& chunk : s.chunks[t]->chunks) drawn.extend(chunk.bounds);
            const Camera* camera = nullptr;
            r.view<Camera>().each([&](const Camera& c) {
              if (!camera) camera = &c;
            });
            if (camera)
              r.resource<pc::PointDrawSettings>().render.point_size =
                  pc::auto_point_size(drawn, stats.drawn_points, *camera, height);
          }
          if (settled < frames) return;
          r.resource<ScreenshotRequests>().capture = true;
          r.resource<AppExit>().requested = true;
        },
        "render_when_streamed");
  }
  if (virtualized) {
    engine.add_system(
        MainStage::Update,
        [settled = uint64_t(0), frames = uint64_t(args.frames), max_frames = args.max_frames,
         frame = uint64_t(0)](Registry& r) mutable {
          const auto& stats = r.resource<pc::VirtualCloudStats>();
          const bool capped = ++frame >= max_frames;
          if ((!stats.settled || stats.selections == 0) && !capped) {
            pc::wait_for_virtual_loads(r.resource<pc::VirtualCloudHandle>(), 0.1);
            return;
          }
          if (settled == 0 && capped && !stats.settled)
            STIPPLE_WARN("--max-frames {} reached while points were still loading", max_frames);
          if (++settled < frames) return;
          r.resource<ScreenshotRequests>().capture = true;
          r.resource<AppExit>().requested = true;
        },
        "render_when_loaded");
  }
  float point_size = virtualized ? 1.0f
                     : compute   ? pc::compute_point_size(settings.render)
                                 : settings.render.point_size;
  const auto load_end = std::chrono::steady_clock::now();

  engine.run();
  engine.shutdown();
  // After the run: a tileset's attributes are known once its tiles are drawn.
  result.color_source =
      virtualized ? "rgb"  // the pointlet cache keeps RGB
                  : pc::color_mode_name(pc::resolve_color_mode(
                        engine.main().resource<pc::SceneInfo>().attributes, settings.render.color));
  if (tileset) {
    point_size = engine.main().resource<pc::PointDrawSettings>().render.point_size;
    if (const uint64_t more =
            tiles3d::unreported_tile_problems(engine.main().resource<tiles3d::TilesetStream>()))
      STIPPLE_WARN("{} more tiles had the problems above (each kind is reported once)", more);
  }
  result.image = std::move(engine.render().resource<CapturedFrame>().image);
  if (result.image.rgba.empty()) fail("no frame was drawn: nothing to return");
  result.compute = compute;
  result.renderer_reason = std::move(renderer_reason);
  result.point_size = point_size;
  result.stats = engine.render().resource<RenderStats>();
  result.adapter = engine.main().resource<GpuContext>()->description;
  const auto& pool = engine.render().resource<FrameGraph>().pool;
  result.transient_textures_created = pool.stats.textures_created;
  result.transient_buffers_created = pool.stats.buffers_created;
  result.load_seconds = std::chrono::duration<double>(load_end - start).count();
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace stipple::scene
