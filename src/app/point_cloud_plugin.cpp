#include "app/point_cloud_plugin.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include <glm/geometric.hpp>

#include "core/error.hpp"
#include "core/log.hpp"
#include "engine/camera.hpp"
#include "engine/engine.hpp"
#include "engine/render_plugins.hpp"
#include "engine/sync.hpp"
#include "engine/transform.hpp"
#include "pointcloud/point_renderer.hpp"

namespace stipple::app {
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
};

// Render-world resource: the pipeline for the current target format.
struct PointPipelineCache {
  std::unique_ptr<pc::PointPipeline> pipeline;
  WGPUTextureFormat format = WGPUTextureFormat_Undefined;
};

// Main-world resource: what the entity was loaded from.
struct LoadedInputs {
  PointCloudInputs inputs;
  pc::ColorMode color = pc::ColorMode::Auto;
  Entity entity;
};

PointCloudData make_data(pc::PointCloud cloud, uint64_t generation) {
  PointCloudData data;
  data.chunk_bounds = chunk_bounds(cloud);
  data.cloud = std::make_shared<const pc::PointCloud>(std::move(cloud));
  data.generation = generation;
  return data;
}

void reload_on_color_change(Registry& main) {
  auto& loaded = main.resource<LoadedInputs>();
  const auto& settings = main.resource<PointDrawSettings>();
  if (settings.color == loaded.color || !main.alive(loaded.entity)) return;
  auto& data = main.get<PointCloudData>(loaded.entity);
  data = make_data(load_inputs(loaded.inputs, settings.color), data.generation + 1);
  loaded.color = settings.color;
  main.resource<SceneInfo>().color_source = data.cloud->color_source;
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

Camera render_camera(const ExtractedCamera& c) {
  Camera camera;
  camera.position = c.position;
  camera.orientation = c.rotation;
  camera.fov_y = c.fov_y;
  camera.near_plane = c.near_plane;
  return camera;
}

// The one call into the point pipeline: swapped for pc::add_point_cloud_passes once it exists.
void add_scene_passes(gpu::RenderGraph& graph, pc::PointPipeline& pipeline,
                      const pc::GpuPointCloud& cloud, const Camera& camera,
                      const PointDrawSettings& settings, uint32_t width, uint32_t height) {
  pc::PointStyle style;
  style.point_size = settings.point_size;
  style.round = settings.round;
  style.background = settings.background;
  pc::add_point_pass(graph, pipeline, cloud, camera, style, width, height);
}

void queue_point_clouds(Registry& render) {
  auto& fg = render.resource<FrameGraph>();
  if (!fg.active) return;
  const auto& target = render.resource<RenderTarget>();
  const ExtractedCamera* extracted = nullptr;
  render.view<ExtractedCamera>().each([&](const ExtractedCamera& c) {
    if (!extracted) extracted = &c;
  });
  if (!extracted) return;
  auto& cache = render.resource<PointPipelineCache>();
  if (!cache.pipeline || cache.format != target.format) {
    cache.pipeline = std::make_unique<pc::PointPipeline>(pc::create_point_pipeline(
        *render.resource<GpuContext>(), target.format, WGPUTextureFormat_Depth32Float));
    cache.format = target.format;
  }
  const auto& settings = render.resource<PointDrawSettings>();
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
    Camera camera = render_camera(*extracted);
    camera.position -= r.translation;  // a translated cloud is the camera moved the other way
    r.drawn_ids = select_chunks(r.gpu_bounds, r.gpu_counts, camera.position, settings.budget);
    for (uint32_t id : r.drawn_ids) {
      r.drawn->point_count += r.all.chunks[id].count;
      r.drawn->chunks.push_back(std::move(r.all.chunks[id]));
    }
    add_scene_passes(fg.graph, *cache.pipeline, *r.drawn, camera, settings, target.width,
                     target.height);
    stats.points_drawn += r.drawn->point_count;
    stats.points_total = r.all.point_count;
    drawn_one = true;
  });
}

}  // namespace

pc::PointCloud load_inputs(const PointCloudInputs& inputs, pc::ColorMode color) {
  pc::PointCloud cloud;
  if (inputs.files.empty()) {
    const pc::SceneParams& scene = inputs.scene;
    io::PointBatch batch;
    const uint64_t block = 1 << 20;
    Aabb bounds = pc::scene_bounds(scene);
    for (uint64_t first = 0; first < scene.point_count; first += block) {
      batch.clear();
      pc::generate_scene(scene, first, std::min(block, scene.point_count - first), batch);
      pc::append_batch(cloud, batch, color, 8, {bounds.min.z + 20.0, bounds.max.z - 60.0},
                       std::min<uint64_t>(block, inputs.chunk_points));
    }
    STIPPLE_INFO("built-in scene: {} points", cloud.point_count);
  } else {
    pc::LoadOptions options;
    options.color = color;
    options.chunk_points = inputs.chunk_points;
    options.progress = inputs.progress;
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
  const glm::dvec3 dir = glm::normalize(direction);
  double best_t = std::numeric_limits<double>::infinity();
  std::optional<glm::dvec3> best;
  const auto& chunks = data.cloud->chunks;
  for (size_t c = 0; c < chunks.size(); ++c) {
    const Aabb& box = data.chunk_bounds[c];
    if (box.empty()) continue;
    // Bounding sphere against the cone: skip chunks wholly outside it or behind a better hit.
    glm::dvec3 center = box.center();
    double radius = glm::length(box.size()) * 0.5;
    glm::dvec3 v = center - origin;
    double t = glm::dot(v, dir);
    if (t + radius < 0 || t - radius > best_t) continue;
    double off_axis = glm::length(v - t * dir);
    if (off_axis - radius > tan_radius * std::max(t + radius, 0.0)) continue;
    const glm::dvec3 rel_origin = origin - chunks[c].origin;
    for (const auto& p : chunks[c].vertices) {
      glm::dvec3 w = glm::dvec3(p.x, p.y, p.z) - rel_origin;
      double tp = glm::dot(w, dir);
      if (tp <= 0 || tp >= best_t) continue;
      glm::dvec3 perpendicular = w - tp * dir;
      if (glm::dot(perpendicular, perpendicular) > tan_radius * tan_radius * tp * tp) continue;
      best_t = tp;
      best = chunks[c].origin + glm::dvec3(p.x, p.y, p.z);
    }
  }
  return best;
}

void PointCloudPlugin::build(Engine& engine) {
  Registry& main = engine.main();
  pc::PointCloud cloud = load_inputs(inputs, settings.color);
  if (cloud.point_count == 0) fail("nothing to render: the input holds no points");
  SceneInfo info;
  info.world_bounds = cloud.world_bounds;
  info.points = cloud.point_count;
  info.color_source = cloud.color_source;
  info.name = inputs.files.empty() ? "procedural scene" : inputs.files.front().filename().string();
  main.insert_resource(info);

  Entity e = main.create();
  main.emplace<PointCloudData>(e, make_data(std::move(cloud), 0));
  main.emplace<Transform>(e);
  main.emplace<SyncTo<RenderWorldTag>>(e);
  main.insert_resource(LoadedInputs{inputs, settings.color, e});
  main.insert_resource(settings);
  engine.render().insert_resource(settings);
  engine.render().insert_resource(PointPipelineCache{});

  engine.add_system(MainStage::Update, reload_on_color_change, "reload_on_color_change");
  engine.add_system(MainStage::Extract, extract_point_clouds, "extract_point_clouds");
  engine.add_system(RenderStage::Prepare, upload_point_clouds, "upload_point_clouds");
  engine.add_system(RenderStage::Queue, queue_point_clouds, "queue_point_clouds");
}

}  // namespace stipple::app
