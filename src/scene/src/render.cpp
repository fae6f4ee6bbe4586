// render_image: headless rendering composed from engine plugins (the engine's core plugins, the
// device and frame graph, the scene's plugin and an offscreen target), returning the last frame.
#include "stipple/scene/render.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <exception>
#include <filesystem>
#include <memory>
#include <thread>
#include <utility>
#include <vector>

#include <fmt/format.h>

#include "stipple/core/error.hpp"
#include "stipple/core/log.hpp"
#include "stipple/engine/plugins.hpp"
#include "stipple/io/point_batch.hpp"
#include "stipple/math/camera.hpp"
#include "stipple/pointcloud/compute_raster.hpp"
#include "stipple/pointcloud/point_cloud_plugin.hpp"
#include "stipple/pointcloud/virtual_cloud.hpp"
#include "stipple/tiles3d/splat_stream.hpp"
#include "stipple/tiles3d/tileset_plugin.hpp"
#include "virtual_scene.hpp"

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
  add_engine_core(engine, {args.backend, args.pipelined, true, args.dump_graph});
  ScenePlan plan = plan_scene(args.scene, *engine.render().resource<GpuContext>());
  const bool tileset = plan.source.streamed(), virtualized = plan.source.virtualized;
  const bool splat_stream = !plan.splat_tileset.empty();
  add_scene_plugin(engine, plan);
  // Streamed sources load what the view needs while frames run, and so does the virtualized
  // path: the image is kept once nothing is loading any more (or at max_frames).
  HeadlessTargetPlugin target{args.width, args.height, "", 0};
  if (!tileset && !virtualized && !splat_stream) {
    target.frames = args.frames;
    target.capture = true;
  }
  engine.add_plugin(std::move(target));

  const SceneView view{args.width,   args.height,    args.camera,
                       args.azimuth, args.elevation, args.fov};
  place_camera(engine, plan, view, true);
  auto& settings = engine.main().resource<pc::PointDrawSettings>();
  if (!args.quiet)
    std::printf("renderer: %s (%s)\n", plan.compute() ? "compute" : "billboard",
                plan.renderer_reason.c_str());
  if (tileset) {
    // Frames run while tiles stream in (waiting for a load between frames); once settled,
    // `frames` more frames run and the last is kept.
    settle_streamed_scene(engine, plan, view, args.max_frames);
    engine.add_system(
        MainStage::Update,
        [frames = uint64_t(args.frames)](Registry& r) {
          const StreamSettle& settle = r.resource<StreamSettle>();
          if (settle.loading) {
            r.resource<tiles3d::TilesetStream>().streamer->wait_for_progress();
            return;
          }
          // A splat tileset beside: it settles too (its own system waits for its loads).
          if (const auto* s = r.try_resource<tiles3d::StreamedSplats>(); s && !s->idle) return;
          if (settle.settled < frames) return;
          r.resource<ScreenshotRequests>().capture = true;
          r.resource<AppExit>().requested = true;
        },
        "render_when_streamed");
  }
  if (splat_stream) {
    // The splat tileset streams in while frames run (waiting for a load between frames); once
    // idle, `frames` more frames run and the last is kept (unless a streamed point source
    // decides that, above).
    engine.add_system(
        MainStage::Update,
        [settled = uint64_t(0), frames = uint64_t(args.frames), max_frames = args.max_frames,
         points_decide = tileset](Registry& r) mutable {
          const auto& s = r.resource<tiles3d::StreamedSplats>();
          const bool capped = s.frames >= max_frames;
          if (!s.idle && !capped) {
            s.streamer->wait_for_progress();
            return;
          }
          if (points_decide) return;
          if (settled == 0 && !s.idle)
            STIPPLE_WARN("--max-frames {} reached before the splat tileset was streamed",
                         max_frames);
          if (++settled < frames) return;
          r.resource<ScreenshotRequests>().capture = true;
          r.resource<AppExit>().requested = true;
        },
        "render_when_splats_streamed");
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
  const bool compute = plan.compute();
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
  result.splats = plan.splat_count() + drawn_splats(engine.main());
  result.renderer_reason = std::move(plan.renderer_reason);
  result.point_size = point_size;
  result.stats = engine.render().resource<RenderStats>();
  result.adapter = engine.main().resource<GpuContext>()->description;
  const auto& pool = engine.render().resource<FrameGraph>().pool;
  result.transient_textures_created = pool.stats.textures_created;
  result.transient_buffers_created = pool.stats.buffers_created;
  result.load_seconds = std::chrono::duration<double>(load_end - start).count();
  if (const auto* cache = engine.main().try_resource<pc::VirtualCloudCache>();
      cache && cache->built) {
    result.cache_built = true;
    result.cache_build = cache->build;
  }
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

RenderResult render_progressive(const RenderOptions& options, uint64_t sample_points,
                                const std::function<void(const RenderResult&)>& first) {
  const SceneSource source = classify_scene(options.scene);
  if (source.kind != SourceKind::PointFiles) return render_image(options);
  // The cache builds beside the first image only where the full render needs one.
  std::exception_ptr build_error;
  std::thread builder;
  try {
    // The sample is read before the build starts: on few cores the build's reads and sorting
    // would hold the sample's up several times over.
    pc::LoadOptions load;
    load.sample = std::max<uint64_t>(sample_points, 1);
    load.chunk_points = options.scene.chunk_points;
    load.progress = false;
    load.keep_extras = options.scene.keep_extras || options.scene.render.filter.needs_extras();
    const std::vector<std::filesystem::path> files(options.scene.inputs.begin(),
                                                   options.scene.inputs.end());
    RenderOptions sample = options;
    sample.scene.points = std::make_shared<const pc::PointCloud>(pc::load_point_cloud(files, load));
    sample.scene.inputs.clear();
    sample.scene.force_virtual = false;
    sample.frames = 1;
    sample.quiet = true;
    if (source.virtualized)
      builder = std::thread([&] {
        try {
          build_virtual_cache(options.scene, source.host_budget);
        } catch (...) {
          build_error = std::current_exception();
        }
      });
    first(render_image(sample));
  } catch (...) {
    if (builder.joinable()) builder.join();
    throw;
  }
  if (builder.joinable()) builder.join();
  if (build_error) std::rethrow_exception(build_error);
  return render_image(options);
}

}  // namespace stipple::scene
