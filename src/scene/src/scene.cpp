#include "stipple/scene/scene.hpp"

#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <stdexcept>
#include <utility>

#include <fmt/format.h>

#include "stipple/core/error.hpp"
#include "stipple/core/log.hpp"
#include "stipple/core/memory.hpp"
#include "stipple/engine/engine.hpp"
#include "stipple/engine/plugins.hpp"
#include "stipple/engine/render_plugins.hpp"
#include "stipple/io/copc.hpp"
#include "stipple/io/ept.hpp"
#include "stipple/io/fetch.hpp"
#include "stipple/io/las.hpp"
#include "stipple/io/procedural.hpp"
#include "stipple/io/splat_readers.hpp"
#include "stipple/io/tileset.hpp"
#include "stipple/math/geo.hpp"
#include "stipple/math/sun.hpp"
#include "stipple/pointcloud/compute_raster.hpp"
#include "stipple/pointcloud/point_cloud_plugin.hpp"
#include "stipple/pointcloud/scene.hpp"
#include "stipple/renderer/gpu.hpp"
#include "stipple/splats/splat_plugin.hpp"
#include "stipple/tiles3d/render_load.hpp"
#include "stipple/tiles3d/splat_stream.hpp"
#include "stipple/tiles3d/tileset_plugin.hpp"
#include "virtual_scene.hpp"

namespace stipple::scene {

namespace {

uint64_t host_budget(const SceneOptions& options) {
  if (!options.host_memory.empty()) return parse_size(options.host_memory);
  const long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGE_SIZE);
  return pages > 0 && page > 0 ? uint64_t(pages) * uint64_t(page) / 4 : uint64_t(4) << 30;
}

}  // namespace

SceneSource classify_scene(const SceneOptions& options) {
  SceneSource source;
  source.host_budget = host_budget(options);
  if (options.points) {
    if (!options.inputs.empty()) fail("points in memory and input files cannot be drawn together");
    source.kind = SourceKind::Memory;
    source.points = options.points->point_count;
    return source;
  }
  if (options.inputs.empty()) {
    source.points = options.scene_points;
    return source;
  }
  // One streamed source alone; otherwise every input is a point file (the LAS reader says what
  // is wrong with one that is not).
  const io::SourceFormat first = io::source_format(options.inputs[0]);
  if (options.inputs.size() == 1 && io::is_streamed(first)) {
    source.kind = SourceKind::Streamed;
    source.format = first;
    if (first == io::SourceFormat::Copc) {
      // The header and VLRs only: the plugin opens the hierarchy (and reads the root node).
      const io::Fetcher fetcher = [](const std::string& uri) { return io::fetch(uri); };
      source.points = io::open_copc(options.inputs[0], fetcher)->header.point_count;
    }
    return source;
  }
  source.kind = SourceKind::PointFiles;
  for (const auto& in : options.inputs) source.points += io::read_las_header(in).point_count;
  // GPS-time and point-source filters are drawn by the billboard path: the in-memory path keeps
  // them possible.
  if (options.force_virtual) {
    source.virtualized = true;
    source.virtual_reason = "--virtual";
  } else if (!options.render.filter.needs_extras()) {
    // The in-memory path holds about 40 bytes a point (chunks, upload, batches).
    const uint64_t need = source.points * 40;
    if (need > source.host_budget) {
      source.virtualized = true;
      source.virtual_reason = fmt::format(
          "{} points need about {:.1f} GiB in memory, over the host budget of "
          "{:.1f} GiB (--host-memory)",
          source.points, double(need) / (1 << 30), double(source.host_budget) / (1 << 30));
    }
  }
  return source;
}

double max_sse_for(const SceneOptions& options, const SceneSource& source) {
  if (options.max_sse > 0) return options.max_sse;
  // COPC, Potree and EPT nodes' error is their point spacing: refine down to 2 px.
  return source.streamed() && source.format != io::SourceFormat::Tileset ? 2.0 : 16.0;
}

void apply_filters(SceneOptions& options) {
  options.render.filter = make_filter(options.filters);
  options.render.clip = make_region(options.filters);
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

Renderer resolve_renderer(const SceneOptions& options, const SceneSource& source,
                          const gpu::Context& ctx, std::string* reason) {
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
  if (source.virtualized) return say(Renderer::Compute, "auto: the virtualized path draws with it");
  constexpr uint64_t kComputeFrom = 10'000'000;
  if (source.streamed() && source.format != io::SourceFormat::Copc) {
    // A tileset's size is not known up front (the tiles are read as the view refines): what
    // can be drawn at once is what the memory budget holds.
    const uint64_t points = (options.memory_mb << 20) / pc::kRasterPointBytes;
    if (points >= kComputeFrom)
      return say(Renderer::Compute,
                 fmt::format("auto: up to {} points streamed in --memory-mb {}, on {}", points,
                             options.memory_mb, ctx.description.adapter_type));
    return say(Renderer::Billboard,
               fmt::format("auto: up to {} points streamed in --memory-mb {}, under {}", points,
                           options.memory_mb, kComputeFrom));
  }
  if (source.points >= kComputeFrom)
    return say(Renderer::Compute,
               fmt::format("auto: {} points on {}", source.points, ctx.description.adapter_type));
  return say(Renderer::Billboard, fmt::format("auto: {} points, under {}: point sizes above one "
                                              "pixel",
                                              source.points, kComputeFrom));
}

std::optional<glm::dvec3> scene_lon_lat(const SceneOptions& options, const SceneSource& source,
                                        std::string* why) {
  auto none = [why](std::string reason) -> std::optional<glm::dvec3> {
    if (why) *why = std::move(reason);
    return std::nullopt;
  };
  // A point at the centre of `min`..`max` in `crs` to longitude and latitude.
  auto through = [&none](const io::Crs& crs, const glm::dvec3& min, const glm::dvec3& max,
                         const std::string& what) -> std::optional<glm::dvec3> {
    if (crs.empty()) return none(what + " has no CRS");
    const io::LonLatTransform to_lon_lat(crs);
    if (!to_lon_lat.valid())
      return none(fmt::format("PROJ cannot place {} ({})", what, crs.describe()));
    auto p = to_lon_lat((min + max) * 0.5);
    if (!p) return none(fmt::format("PROJ cannot place the centre of {}", what));
    return p;
  };
  switch (source.kind) {
    case SourceKind::Memory:
      return none("points in memory have no CRS");
    case SourceKind::BuiltIn: {
      io::SceneParams params;
      params.point_count = options.scene_points;
      io::Crs crs;
      crs.epsg = params.epsg;
      const Aabb box = io::scene_bounds(params);
      return through(crs, box.min, box.max, "the built-in scene");
    }
    case SourceKind::PointFiles: {
      const io::LasHeader h = io::read_las_header(options.inputs[0]);
      return through(h.crs, h.min, h.max, options.inputs[0]);
    }
    case SourceKind::Streamed: {
      const io::Tileset ts = io::load_tileset(options.inputs[0]);
      if (ts.copc)
        return through(ts.copc->header.crs, ts.copc->header.min, ts.copc->header.max,
                       options.inputs[0]);
      if (ts.ept) {
        io::Crs crs;
        crs.wkt = ts.ept->wkt;
        return through(crs, ts.ept->data_min, ts.ept->data_max, options.inputs[0]);
      }
      if (ts.potree || ts.tiles.empty()) return none(options.inputs[0] + " has no CRS");
      // 3D Tiles are geocentric (ECEF) when geo-referenced; a local frame has no location.
      const glm::dvec3 c = ts.tiles[0].box.center;
      if (glm::length(c) < 1e6) return none(options.inputs[0] + " is in a local frame, not ECEF");
      return geo::ecef_to_geodetic(c);
    }
  }
  return none("unknown source");
}

void resolve_sun(SceneOptions& options, const SceneSource& source) {
  if (options.sun_time.empty()) return;
  const solar::SunTime time = solar::parse_sun_time(options.sun_time);
  std::string why;
  const auto where = scene_lon_lat(options, source, &why);
  if (!where)
    fail("--sun-time needs the data's location, but {}: give the sun as --sun AZIMUTH,ELEVATION",
         why);
  const solar::SolarPosition sun =
      solar::solar_position(solar::julian_day_utc(time, where->x), where->y, where->x);
  options.render.sky.enabled = true;
  options.render.sky.sun_azimuth_deg = sun.azimuth_deg;
  options.render.sky.sun_elevation_deg = sun.elevation_deg;
  STIPPLE_INFO("sun at {} ({}) at lon {:.4f}, lat {:.4f}: azimuth {:.2f}, elevation {:.2f} deg",
               options.sun_time, time.local ? "local mean solar time" : "civil time", where->x,
               where->y, sun.azimuth_deg, sun.elevation_deg);
}

std::vector<std::string> expand_input_folders(const std::vector<std::string>& inputs) {
  namespace fs = std::filesystem;
  std::vector<std::string> out;
  for (const std::string& in : inputs) {
    std::error_code ec;
    if (io::is_url(in) || !fs::is_directory(in, ec)) {
      out.push_back(in);
      continue;
    }
    auto lower_extension = [](const fs::path& p) {
      std::string e = p.extension().string();
      for (char& c : e) c = char(std::tolower(static_cast<unsigned char>(c)));
      return e;
    };
    std::vector<std::string> tiles, others;
    for (const fs::directory_entry& e : fs::directory_iterator(in)) {
      const std::string name = e.path().filename().string();
      // The collection's own pointlet cache lives beside its first tile (and its temporaries
      // while it is built); hidden files are no survey's data.
      if (name.starts_with(".") || name.find(".pointlets") != std::string::npos) continue;
      const std::string ext = lower_extension(e.path());
      if (e.is_directory() || (ext != ".las" && ext != ".laz"))
        others.push_back(name);
      else
        tiles.push_back(e.path().string());
    }
    // Surveys come with sidecars (.prj, .lax indexes, reports, metadata folders): passed over,
    // and said once, so that a file misnamed as something else is not silently left out.
    if (tiles.empty())
      fail("{}: the folder holds no .las or .laz file{}", in,
           others.empty() ? "" : fmt::format(" ({} other entries)", others.size()));
    if (!others.empty()) {
      std::sort(others.begin(), others.end());
      STIPPLE_WARN("{}: {} tiles; passed over what is not .las or .laz: {}{}", in, tiles.size(),
                   others.front(),
                   others.size() > 1 ? fmt::format(" (and {} more)", others.size() - 1) : "");
    }
    std::sort(tiles.begin(), tiles.end());
    out.insert(out.end(), tiles.begin(), tiles.end());
  }
  return out;
}

ScenePlan plan_scene(const SceneOptions& options, const gpu::Context& ctx) {
  ScenePlan plan;
  plan.options = options;
  plan.options.inputs = expand_input_folders(options.inputs);
  plan.renderer_auto = options.renderer == Renderer::Auto;
  // Splat files read here and drawn beside whatever the other inputs are; alone, over an empty
  // cloud (so the frame, its camera and the summary are those of a point scene).
  if (!options.points) {
    std::vector<std::string> others;
    for (const auto& in : plan.options.inputs) {
      if (io::is_splat_tileset_path(in)) {
        if (!plan.splat_tileset.empty())
          fail("{} and {}: one splat tileset at a time", plan.splat_tileset, in);
        plan.splat_tileset = in;
      } else if (io::is_splat_path(in)) {
        plan.splats.push_back(std::make_shared<const io::SplatSet>(io::read_splats(in)));
      } else {
        others.push_back(in);
      }
    }
    if (!plan.splats.empty() || !plan.splat_tileset.empty()) {
      plan.options.inputs = std::move(others);
      if (plan.options.inputs.empty()) {
        // An empty cloud with the splats' bounds, so that what reads the scene's bounds (near
        // and far planes, the page's report) sees the splats, not an empty box.
        auto empty = std::make_shared<pc::PointCloud>();
        for (const auto& set : plan.splats) {
          if (set->size() == 0) continue;
          const Aabb b = splats::splat_bounds(*set);
          empty->world_bounds.extend(b);
          for (int c = 0; c < 8; ++c)
            empty->source_bounds.extend(y_up_to_z_up(
                {c & 1 ? b.max.x : b.min.x, c & 2 ? b.max.y : b.min.y, c & 4 ? b.max.z : b.min.z}));
        }
        if (!plan.splat_tileset.empty()) {
          // The root volume (the tiles arrive as they stream), in the frame the splats draw in.
          const io::Tileset ts = io::load_tileset(plan.splat_tileset);
          const Aabb b = tiles3d::world_bounds(ts, tiles3d::StreamedSplats{}.world_from_tileset);
          empty->world_bounds.extend(b);
          for (int c = 0; c < 8; ++c)
            empty->source_bounds.extend(y_up_to_z_up(
                {c & 1 ? b.max.x : b.min.x, c & 2 ? b.max.y : b.min.y, c & 4 ? b.max.z : b.min.z}));
        }
        plan.options.points = std::move(empty);
      }
    }
  }
  apply_filters(plan.options);
  plan.source = classify_scene(plan.options);
  resolve_sun(plan.options, plan.source);
  plan.options.renderer = resolve_renderer(plan.options, plan.source, ctx, &plan.renderer_reason);
  // Blending's form on the compute rasterizer is HQS: a streamed source auto-drawn there keeps
  // it.
  if (options.renderer == Renderer::Auto && plan.compute() && plan.source.streamed())
    plan.options.hqs = plan.options.hqs || plan.options.render.splat == pc::SplatMode::Blend;
  return plan;
}

void add_engine_core(Engine& engine, const EngineCore& core) {
  engine.add_plugins(TimePlugin{}, TransformPlugin{}, CameraPlugin{});
  if (core.pipelined) engine.add_plugin(PipelinedRenderingPlugin{});
  GpuPlugin gpu;
  gpu.options.backend = core.backend;
  gpu.options.optional_features = pc::compute_raster_features();
  engine.add_plugin(std::move(gpu));
  RenderGraphPlugin graph;
  graph.keep_history = core.keep_history;
  graph.dump_graph = core.dump_graph;
  graph.wait_for_gpu = core.wait_for_gpu;
  graph.history_limit = core.history_limit;
  graph.max_frames_in_flight = core.max_frames_in_flight;
  engine.add_plugin(std::move(graph));
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
  main.view<splats::SplatData>().each([&](const splats::SplatData& data) {
    if (data.set && data.set->size() > 0) fit.add_corners(splats::splat_bounds(*data.set));
  });
  if (fit.empty()) fit_virtual_scene(fit, main);
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

uint64_t ScenePlan::splat_count() const {
  uint64_t n = 0;
  for (const auto& set : splats) n += set->size();
  return n;
}

uint64_t drawn_splats(Registry& main) {
  const auto* stream = main.try_resource<tiles3d::StreamedSplats>();
  return stream ? stream->drawn_splats : 0;
}

namespace {

// The plugin that reads or streams the points (add_scene_plugin's first half).
void add_scene_points_plugin(Engine& engine, const ScenePlan& plan);

// Marks the SplatData entity that shows a streamed splat tileset.
struct StreamedSplatEntity {};

// Added after the scene's plugin, so the splats' passes follow the points' (splat_plugin.hpp).
void add_splat_plugin(Engine& engine, const ScenePlan& plan) {
  if (plan.splats.empty() && plan.splat_tileset.empty()) return;
  splats::SplatPlugin plugin;
  plugin.sets = plan.splats;
  plugin.settings.background = plan.options.render.background;
  plugin.settings.rasterizer = plan.options.splat_rasterizer;
  engine.add_plugin(std::move(plugin));
  if (plan.splat_tileset.empty()) return;
  // The streamed tileset: tiles3d lists the drawn tiles' splats (StreamedSplats), which one
  // SplatData entity hands to the SplatPlugin as the parts of one set, so every drawn tile is
  // sorted with the others.
  // The wiring is here because neither module may see the other (DESIGN.md's table).
  tiles3d::SplatTilesetPlugin stream;
  stream.uri = plan.splat_tileset;
  stream.streamer.traversal.max_sse = plan.options.max_sse > 0 ? plan.options.max_sse : 16.0;
  stream.streamer.traversal.memory_budget = plan.options.memory_mb << 20;
  stream.streamer.traversal.point_budget = plan.options.splat_budget;
  engine.add_plugin(std::move(stream));
  Registry& main = engine.main();
  const Entity e = main.create();
  main.emplace<splats::SplatData>(e);
  main.emplace<StreamedSplatEntity>(e);
  main.emplace<Transform>(e);
  main.emplace<SyncTo<RenderWorldTag>>(e);
  engine.add_system(
      MainStage::PostUpdate,
      [](Registry& r) {
        const auto& stream = r.resource<tiles3d::StreamedSplats>();
        r.view<splats::SplatData, StreamedSplatEntity>().each(
            [&](splats::SplatData& data, const StreamedSplatEntity&) {
              if (data.generation == stream.generation) return;
              data.parts = stream.parts;
              data.parts_transform = stream.transform;
              data.generation = stream.generation;
            });
      },
      "show_streamed_splats");
}

}  // namespace

void add_scene_plugin(Engine& engine, const ScenePlan& plan) {
  add_scene_points_plugin(engine, plan);
  add_splat_plugin(engine, plan);
}

namespace {

void add_scene_points_plugin(Engine& engine, const ScenePlan& plan) {
  const SceneOptions& options = plan.options;
  const bool compute = options.renderer == Renderer::Compute;
  if (plan.source.streamed()) {
    // Streamed frame by frame with the camera (out of core).
    tiles3d::TilesetPlugin tiles;
    tiles.compute = compute;
    tiles.raster.hqs = options.hqs;
    tiles.raster.fill_radius = options.fill_radius < 0 ? 0u : uint32_t(options.fill_radius);
    tiles.raster.occlusion_beta = options.occlusion_beta;
    tiles.uri = options.inputs[0];
    tiles.format = plan.source.format;
    tiles.streamer.traversal.max_sse = max_sse_for(options, plan.source);
    tiles.streamer.traversal.memory_budget = options.memory_mb << 20;
    tiles.streamer.traversal.point_budget = options.budget;
    tiles.render = options.render;
    engine.add_plugin(std::move(tiles));
    return;
  }
  if (plan.source.virtualized) {
    add_virtual_scene(engine, plan);
    return;
  }
  pc::PointCloudPlugin points;
  points.inputs.files.assign(options.inputs.begin(), options.inputs.end());
  points.inputs.points = options.points;
  points.inputs.scene.point_count = options.scene_points;
  points.inputs.scene.seed = options.seed;
  points.inputs.chunk_points = options.chunk_points;
  points.inputs.keep_extras = options.keep_extras || options.render.filter.needs_extras();
  points.inputs.allow_empty = !plan.splats.empty() || !plan.splat_tileset.empty();
  points.settings.render = options.render;
  points.settings.budget = options.budget;
  points.settings.compute = compute;
  points.settings.hqs = options.hqs;
  points.settings.fill_radius = options.fill_radius < 0 ? 0u : uint32_t(options.fill_radius);
  points.settings.occlusion_beta = options.occlusion_beta;
  engine.add_plugin(std::move(points));
}

}  // namespace

Camera place_camera(Engine& engine, ScenePlan& plan, const SceneView& view,
                    bool one_pixel_compute) {
  Registry& main = engine.main();
  const Camera camera = scene_camera(main, view.camera, view.width, view.height, view.azimuth,
                                     view.elevation, view.fov);
  main.emplace<Camera>(main.create(), camera);
  auto& settings = main.resource<pc::PointDrawSettings>();
  const bool sized_by_data = settings.render.point_size <= 0;
  size_t clouds = 0;
  main.view<pc::PointCloudData>().each([&](const pc::PointCloudData& data) {
    ++clouds;
    if (settings.render.point_size <= 0)
      settings.render.point_size =
          pc::auto_point_size(*data.cloud, camera, std::max(view.height, 1u));
  });
  // Streamed tiles arrive later: a size that suits the default screen-space error until then.
  if (plan.source.streamed() && settings.render.point_size <= 0) settings.render.point_size = 2.0f;
  if (one_pixel_compute && plan.renderer_auto && !plan.compute() && !plan.source.streamed() &&
      sized_by_data && settings.render.point_size <= 1.0f && clouds > 0 &&
      !plan.options.render.filter.needs_extras()) {
    settings.compute = true;
    settings.hqs = settings.render.splat == pc::SplatMode::Blend;
    plan.options.renderer = Renderer::Compute;
    plan.options.hqs = settings.hqs;
    plan.renderer_reason = "auto: 1-pixel points";
  }
  return camera;
}

void settle_streamed_scene(Engine& engine, const ScenePlan& plan, const SceneView& view,
                           uint64_t max_frames) {
  Registry& main = engine.main();
  main.insert_resource(StreamSettle{});
  const bool auto_size = plan.options.render.point_size <= 0;
  engine.add_system(
      MainStage::Update,
      [max_frames, view, auto_size, reframe = view.camera.empty(),
       memory_mb = plan.options.memory_mb, point_budget = plan.options.budget,
       max_sse = max_sse_for(plan.options, plan.source),
       backdrop = plan.options.render.sky.enabled ? "sky" : "background",
       uri = plan.options.inputs[0]](Registry& r) mutable {
        StreamSettle& settle = r.resource<StreamSettle>();
        auto& s = r.resource<tiles3d::TilesetStream>();
        const auto& stats = r.resource<tiles3d::TilesetStats>();
        settle.capped = stats.frames >= max_frames;
        // The traversal keeps the selection within the memory budget (coarser tiles where the
        // view wants more), so the streamer goes idle in every case.
        settle.loading = !stats.idle && !settle.capped;
        if (settle.loading) return;
        // Framed from the source's volume (which may be far larger than the data) until the
        // first tiles are in: then once from their points, and streamed again for that view.
        if (reframe && !settle.capped && stats.drawn_points > 0) {
          reframe = false;
          ViewFit fit(view.width, view.height, view.azimuth, view.elevation, view.fov);
          tiles3d::fit_drawn_tiles(fit, s);
          r.view<Camera>().each([&](Camera& c) { c = fit.camera(); });
          return;
        }
        if (settle.settled == 0 && !stats.idle)
          STIPPLE_WARN("--max-frames {} reached before the tileset was streamed", max_frames);
        if (settle.settled == 0 && stats.budget_limited && stats.drawn_tiles == 0)
          STIPPLE_WARN(
              "--memory-mb {} is smaller than the coarsest tiles this view needs: "
              "nothing is drawn (raise --memory-mb)",
              memory_mb);
        else if (settle.settled == 0 && stats.budget_limited)
          STIPPLE_WARN(
              "the view wants more than --memory-mb {}{} allow: drawn at a screen-space error "
              "of {:.1f} px instead of --max-sse {} (raise them for more detail)",
              memory_mb, point_budget ? fmt::format(" and --budget {}", point_budget) : "",
              stats.sse_threshold, max_sse);
        else if (settle.settled == 0 && stats.drawn_points == 0) {
          // Content was read and none of it is points (meshes, an empty pnts): an input with
          // no points is an error, as for LAS. Nothing read: no tile is in view.
          if ((stats.loads_completed > 0 || stats.errors > 0) && stats.resident_points == 0)
            fail("{}: nothing to render: the tiles in view hold no points{}", uri,
                 s.first_problem.empty() ? "" : fmt::format(" ({})", s.first_problem));
          STIPPLE_WARN("{}: no tile with points is in view: the image shows the {} only", uri,
                       backdrop);
        }
        if (settle.settled++ == 0 && auto_size && stats.drawn_points > 0) {
          Aabb drawn;
          for (uint32_t t : s.draw)
            for (const auto& chunk : s.chunks[t]->chunks) drawn.extend(chunk.bounds);
          const Camera* camera = nullptr;
          r.view<Camera>().each([&](const Camera& c) {
            if (!camera) camera = &c;
          });
          if (camera)
            r.resource<pc::PointDrawSettings>().render.point_size =
                pc::auto_point_size(drawn, stats.drawn_points, *camera, view.height);
        }
      },
      "settle_streamed_scene");
}

}  // namespace stipple::scene
