#include "stipple/pointcloud/point_cloud_plugin.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <optional>
#include <vector>

#include <glm/geometric.hpp>

#include "stipple/core/error.hpp"
#include "stipple/core/log.hpp"
#include "stipple/engine/camera.hpp"
#include "stipple/engine/engine.hpp"
#include "stipple/engine/render_plugins.hpp"
#include "stipple/engine/sync.hpp"
#include "stipple/engine/transform.hpp"
#include "stipple/pointcloud/compute_raster.hpp"
#include "stipple/pointcloud/picking.hpp"
#include "stipple/pointcloud/point_renderer.hpp"

namespace stipple::pc {
namespace {

// Render-world component on the cloud's twin.
struct RenderPointCloud {
  std::shared_ptr<const pc::PointCloud> cloud;
  std::vector<Aabb> bounds;  // per cloud chunk
  uint64_t generation = 0;
  glm::dvec3 translation{0.0};  // from the entity's GlobalTransform (rotation/scale unsupported)

  uint64_t uploaded_generation = std::numeric_limits<uint64_t>::max();
  pc::GpuPointCloud all;  // every non-empty chunk, upload order (drawn ones moved out)
  std::vector<Aabb> gpu_bounds;
  std::vector<uint32_t> gpu_counts;
  // The pass reads this cloud when the graph executes (Draw), so the chunks to draw are moved
  // into it in Queue and back at the next Queue. Boxed: its address must not move.
  std::unique_ptr<pc::GpuPointCloud> drawn = std::make_unique<pc::GpuPointCloud>();
  std::vector<uint32_t> drawn_ids;
  std::vector<uint32_t> last_ids;  // the previous frame's selection
  // The compute rasterizer's batches (built on first use), boxed for the same reason.
  std::unique_ptr<pc::GpuBatchedCloud> batched;
  uint64_t batched_generation = std::numeric_limits<uint64_t>::max();
  bool extras_uploaded = false;  // PointChunk::extras on the GPU (once a filter needed them)
};

// Render-world resource: the pipelines for the current target format.
struct PointPipelineCache {
  std::unique_ptr<pc::PointPipelines> pipelines;
  std::unique_ptr<pc::ComputeRasterPipeline> raster;
  WGPUTextureFormat format = WGPUTextureFormat_Undefined;
};

PointCloudData make_data(std::shared_ptr<const pc::PointCloud> cloud, uint64_t generation) {
  PointCloudData data;
  data.chunk_bounds = chunk_bounds(*cloud);
  data.cloud = std::move(cloud);
  data.generation = generation;
  return data;
}

void extract_point_clouds(Registry& main) {
  Registry& render = *main.resource<RenderWorldRef>();
  render.insert_resource(main.resource<PointDrawSettings>());
  main.view<PointCloudData, RenderEntity>().each(
      [&](Entity e, const PointCloudData& data, const RenderEntity& twin) {
        auto* r = render.try_get<RenderPointCloud>(twin.entity);
        if (!r) r = &render.emplace<RenderPointCloud>(twin.entity);
        if (r->generation != data.generation || !r->cloud) {
          r->cloud = data.cloud;
          r->bounds = data.chunk_bounds;
          r->generation = data.generation;
        }
        const auto* global = main.try_get<GlobalTransform>(e);
        r->translation = global ? global->translation() : glm::dvec3(0.0);
      });
}

void upload_point_clouds(Registry& render) {
  gpu::Context& ctx = *render.resource<GpuContext>();
  render.view<RenderPointCloud>().each([&](RenderPointCloud& r) {
    if (!r.cloud || r.uploaded_generation == r.generation) return;
    r.drawn->chunks.clear();
    r.drawn_ids.clear();
    r.all = pc::upload_point_cloud(ctx, *r.cloud);
    r.extras_uploaded = false;
    // The drawn subset (point budget) needs its own CLOD argument slots, one per chunk at most.
    r.drawn->attributes = r.all.attributes;
    r.drawn->clod_args_stride = r.all.clod_args_stride;
    r.drawn->clod_args = gpu::create_buffer(
        ctx, uint64_t(std::max<size_t>(1, r.all.chunks.size())) * r.all.clod_args_stride,
        WGPUBufferUsage_Storage | WGPUBufferUsage_Indirect | WGPUBufferUsage_CopyDst |
            WGPUBufferUsage_CopySrc,
        "clod-args-drawn");
    // upload_point_cloud skips empty chunks: keep bounds and counts aligned with what it made.
    r.gpu_bounds.clear();
    r.gpu_counts.clear();
    for (size_t i = 0; i < r.cloud->chunks.size(); ++i) {
      if (r.cloud->chunks[i].vertices.empty()) continue;
      r.gpu_bounds.push_back(r.bounds[i]);
      r.gpu_counts.push_back(uint32_t(r.cloud->chunks[i].vertices.size()));
    }
    r.uploaded_generation = r.generation;
  });
}

// The one call into the point pipeline.
void add_scene_passes(gpu::RenderGraph& graph, pc::PointPipelines& pipelines,
                      pc::GpuPointCloud& cloud, const Camera& camera,
                      const PointDrawSettings& settings, uint32_t width, uint32_t height) {
  // The depth stays stored for later passes of the frame (splats test against it).
  pc::PointPassTargets targets;
  targets.keep_depth = true;
  pc::add_point_cloud_passes(graph, pipelines, cloud, camera, settings.render, width, height,
                             targets);
}

void queue_point_clouds(Registry& render) {
  auto& fg = render.resource<FrameGraph>();
  if (!fg.active) return;
  const auto& target = render.resource<RenderTarget>();
  const ExtractedCamera* extracted = first_extracted_camera(render);
  if (!extracted) return;
  auto& cache = render.resource<PointPipelineCache>();
  const auto& settings = render.resource<PointDrawSettings>();
  gpu::Context& ctx = *render.resource<GpuContext>();
  if (cache.format != target.format) {
    cache.pipelines.reset();
    cache.raster.reset();
    cache.format = target.format;
  }
  if (!settings.compute && !cache.pipelines)
    cache.pipelines =
        std::make_unique<pc::PointPipelines>(pc::create_point_pipelines(ctx, target.format));
  if (settings.compute && !cache.raster)
    cache.raster = std::make_unique<pc::ComputeRasterPipeline>(
        pc::create_compute_raster_pipeline(ctx, target.format));
  auto& stats = render.resource<RenderStats>();
  bool drawn_one = false;
  render.view<RenderPointCloud>().each([&](RenderPointCloud& r) {
    if (r.uploaded_generation != r.generation) return;
    // Chunks back from the last frame.
    for (size_t i = 0; i < r.drawn_ids.size(); ++i)
      r.all.chunks[r.drawn_ids[i]] = std::move(r.drawn->chunks[i]);
    r.drawn->chunks.clear();
    r.drawn->point_count = 0;
    if (drawn_one) return;  // one pass per frame for now: the first cloud
    Camera camera = to_camera(*extracted);
    camera.position -= r.translation;  // a translated cloud is the camera moved the other way
    if (settings.compute) {
      // The compute rasterizer draws every batch it does not cull (no budget: it is the path
      // for billions of points).
      // Batched once per loaded cloud; the colour mode and its ramps are per-frame uniforms.
      if (!r.batched || r.batched_generation != r.generation) {
        r.batched = std::make_unique<pc::GpuBatchedCloud>(pc::upload_batched_chunks(ctx, *r.cloud));
        r.batched_generation = r.generation;
      }
      pc::ComputeRasterOptions options;
      options.hqs = settings.hqs;
      options.fill_radius = settings.fill_radius;
      options.occlusion_beta = settings.occlusion_beta;
      options.background = settings.render.background;
      options.sky = settings.render.sky;
      options.edl_strength = settings.render.edl ? settings.render.edl_strength : 0.0f;
      options.edl_radius = settings.render.edl_radius;
      options.point_size = compute_point_size(settings.render);
      options.storage_target = (target.usage & WGPUTextureUsage_StorageBinding) != 0;
      options.shading = pc::point_shading(settings.render, r.cloud->attributes);
      options.shading.mode = pc::resolve_color_mode(r.cloud->attributes, options.shading.mode);
      options.translucent = pc::translucent_frame(r.cloud->attributes, options.shading);
      options.filter = settings.render.filter;
      options.clip = settings.render.clip;
      options.highlight = settings.render.highlight;
      options.depth_texture = "depth";  // later passes (splats) test against it
      pc::add_compute_raster_passes(fg.graph, *cache.raster, *r.batched, camera, options,
                                    target.width, target.height);
      stats.points_drawn += r.batched->point_count;
      stats.points_total = r.batched->point_count;
      drawn_one = true;
      return;
    }
    // GPS-time and point-source filters read the chunks' extras: uploaded the first time one
    // is on, and kept (the default path never holds them on the GPU).
    if (settings.render.filter.needs_extras() && !r.extras_uploaded) {
      if (!pc::upload_point_extras(ctx, r.all, *r.cloud))
        STIPPLE_WARN(
            "GPS-time and point-source filters need the points' extras, which were not "
            "loaded for every chunk: those chunks are not filtered on them");
      r.extras_uploaded = true;
      r.drawn->bind_groups_for = nullptr;
    }
    std::vector<uint32_t> ids =
        select_chunks(r.gpu_bounds, r.gpu_counts, camera.position, settings.budget);
    // Each chunk's bind groups point at its CLOD argument slot (its index in the drawn view):
    // a different selection or order must rebuild them.
    if (ids != r.last_ids) r.drawn->bind_groups_for = nullptr;
    r.last_ids = ids;
    r.drawn_ids = std::move(ids);
    for (uint32_t id : r.drawn_ids) {
      r.drawn->point_count += r.all.chunks[id].count;
      r.drawn->chunks.push_back(std::move(r.all.chunks[id]));
    }
    add_scene_passes(fg.graph, *cache.pipelines, *r.drawn, camera, settings, target.width,
                     target.height);
    stats.points_drawn += r.drawn->point_count;
    stats.points_total = r.all.point_count;
    drawn_one = true;
  });
}

}  // namespace

pc::PointCloud load_inputs(const PointCloudInputs& inputs) {
  pc::PointCloud cloud;
  if (inputs.files.empty()) {
    io::SceneParams scene = inputs.scene;
    cloud = pc::generate_scene_cloud(scene, inputs.chunk_points, inputs.keep_extras);
    STIPPLE_INFO("built-in scene: {} points", cloud.point_count);
  } else {
    pc::LoadOptions options;
    options.chunk_points = inputs.chunk_points;
    options.progress = inputs.progress;
    options.keep_extras = inputs.keep_extras;
    cloud = pc::load_point_cloud(inputs.files, options);
  }
  return cloud;
}

std::vector<Aabb> chunk_bounds(const pc::PointCloud& cloud) {
  std::vector<Aabb> bounds(cloud.chunks.size());
  for (size_t i = 0; i < cloud.chunks.size(); ++i) {
    const auto& chunk = cloud.chunks[i];
    Aabb local;
    for (const auto& v : chunk.vertices) local.extend(glm::dvec3(v.x, v.y, v.z));
    if (!local.empty()) bounds[i] = {chunk.origin + local.min, chunk.origin + local.max};
  }
  return bounds;
}

std::vector<uint32_t> select_chunks(const std::vector<Aabb>& bounds,
                                    const std::vector<uint32_t>& counts,
                                    const glm::dvec3& camera_position, uint64_t budget) {
  std::vector<uint32_t> ids(bounds.size());
  std::iota(ids.begin(), ids.end(), 0u);
  if (budget == 0) return ids;
  std::vector<double> distance(bounds.size());
  for (size_t i = 0; i < bounds.size(); ++i) {
    glm::dvec3 nearest = glm::clamp(camera_position, bounds[i].min, bounds[i].max);
    distance[i] = glm::distance(nearest, camera_position);
  }
  std::stable_sort(ids.begin(), ids.end(),
                   [&](uint32_t a, uint32_t b) { return distance[a] < distance[b]; });
  uint64_t total = 0;
  size_t keep = 0;
  while (keep < ids.size() && total + counts[ids[keep]] <= budget) total += counts[ids[keep++]];
  ids.resize(keep);
  return ids;
}

std::optional<glm::dvec3> pick_point(const PointCloudData& data, const glm::dvec3& origin,
                                     const glm::dvec3& direction, double tan_radius) {
  if (!data.cloud) return std::nullopt;
  const PickRay ray{origin, glm::normalize(direction), tan_radius};
  std::optional<PickHit> best;
  const auto& chunks = data.cloud->chunks;
  for (size_t c = 0; c < chunks.size(); ++c)
    pick_in_chunk(chunks[c], data.chunk_bounds[c], ray, best);
  if (!best) return std::nullopt;
  return best->point;
}

namespace {

// ScenePickers entry: every loaded cloud, whatever the point budget draws.
std::optional<PickHit> pick_point_clouds(Registry& main, const PickRay& ray) {
  std::optional<PickHit> best;
  const PickFilter* filter = main.try_resource<PickFilter>();
  main.view<PointCloudData>().each([&](const PointCloudData& data) {
    if (!data.cloud) return;
    const auto& chunks = data.cloud->chunks;
    for (size_t c = 0; c < chunks.size(); ++c)
      pick_in_chunk(chunks[c], data.chunk_bounds[c], ray, best, filter);
  });
  return best;
}

}  // namespace

void remove_point_clouds(Registry& main, Registry& render) {
  std::vector<Entity> clouds;
  main.view<PointCloudData>().each([&](Entity e, const PointCloudData&) { clouds.push_back(e); });
  for (Entity e : clouds) {
    if (const auto* twin = main.try_get<RenderEntity>(e))
      render.remove<RenderPointCloud>(twin->entity);  // the twin itself goes at the next sync
    main.destroy(e);
  }
}

void PointCloudPlugin::build(Engine& engine) {
  Registry& main = engine.main();
  // Points in memory are shared as they are (never modified), not copied.
  const bool in_memory = inputs.points && inputs.files.empty();
  std::shared_ptr<const pc::PointCloud> cloud =
      in_memory ? inputs.points : std::make_shared<const pc::PointCloud>(load_inputs(inputs));
  if (cloud->point_count == 0 && !(in_memory && inputs.allow_empty)) {
    if (in_memory) fail("nothing to render: the points given hold none");
    std::string names;
    for (const auto& f : inputs.files) names += (names.empty() ? "" : ", ") + f.string();
    fail("{}: nothing to render: the {} no points", names,
         inputs.files.size() > 1 ? "inputs hold" : "input holds");
  }
  SceneInfo info;
  info.world_bounds = cloud->world_bounds;
  info.points = cloud->point_count;
  info.attributes = cloud->attributes;
  info.name = in_memory              ? "points in memory"
              : inputs.files.empty() ? "procedural scene"
                                     : inputs.files.front().filename().string();
  main.insert_resource(info);

  Entity e = main.create();
  PointCloudData data = make_data(std::move(cloud), 0);
  if (inputs.files.empty() && !in_memory) data.scene = inputs.scene;
  main.emplace<PointCloudData>(e, std::move(data));
  main.emplace<Transform>(e);
  main.emplace<SyncTo<RenderWorldTag>>(e);
  main.insert_resource(settings);
  engine.render().insert_resource(settings);
  engine.render().insert_resource(PointPipelineCache{});

  add_scene_picker(main, pick_point_clouds);

  engine.add_system(MainStage::Extract, extract_point_clouds, "extract_point_clouds");
  engine.add_system(RenderStage::Prepare, upload_point_clouds, "upload_point_clouds");
  engine.add_system(RenderStage::Queue, queue_point_clouds, "queue_point_clouds");
}

}  // namespace stipple::pc
