#include "stipple/pointcloud/virtual_cloud.hpp"

#include <algorithm>
#include <chrono>
#include <memory>

#include "stipple/core/error.hpp"
#include "stipple/core/log.hpp"
#include "stipple/core/thread_pool.hpp"
#include "stipple/engine/camera.hpp"
#include "stipple/engine/engine.hpp"
#include "stipple/engine/render_plugins.hpp"
#include "stipple/pointcloud/batches.hpp"
#include "stipple/pointcloud/compute_raster.hpp"
#include "stipple/pointcloud/scene.hpp"

namespace stipple::pc {
namespace {

using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
}

// Render-world resource.
struct VirtualCloudRender {
  std::shared_ptr<const PointletCache> cache;
  VirtualCloudOptions options;
  glm::vec3 background{0.0f};
  std::unique_ptr<GpuPointlets> pointlets;
  std::unique_ptr<PointletLodPipeline> lod;
  std::unique_ptr<ComputeRasterPipeline> raster;
  WGPUTextureFormat format = WGPUTextureFormat_Undefined;
  // Boxed: the graph reads it when it executes.
  std::unique_ptr<GpuBatchedCloud> drawn;
  bool have_selection = false;
  ExtractedCamera selected_for;
  uint32_t width = 0, height = 0;
  std::unique_ptr<ThreadPool> pool;
};

bool same_view(const ExtractedCamera& a, const ExtractedCamera& b) {
  return a.position == b.position && a.rotation == b.rotation && a.fov_y == b.fov_y &&
         a.near_plane == b.near_plane;
}

// A pointlet's box in world space (Y up).
void world_box(const PointletEntry& e, glm::dvec3& min, glm::dvec3& size) {
  const glm::dvec3 a = z_up_to_y_up({e.min[0], e.min[1], e.min[2]});
  const glm::dvec3 b = z_up_to_y_up({e.max[0], e.max[1], e.max[2]});
  min = glm::min(a, b);
  size = glm::max(a, b) - min;
}

// The points the LoD asks for, as batches of the compute rasterizer: each pointlet's prefix,
// read from the cache, cut into batches of at most kBatchPoints sharing the pointlet's box.
BatchedCloud load_selection(const PointletCache& cache, const std::vector<uint32_t>& counts,
                            ThreadPool& pool) {
  const auto& table = cache.pointlets();
  std::vector<uint32_t> selected;
  std::vector<uint64_t> first;
  uint64_t total = 0;
  for (uint32_t i = 0; i < counts.size(); ++i)
    if (counts[i] > 0) {
      selected.push_back(i);
      first.push_back(total);
      total += counts[i];
    }
  BatchedCloud out;
  out.coarse.resize(total);
  out.medium.resize(total);
  out.fine.resize(total);
  out.color.resize(total);
  std::vector<std::vector<Batch>> batches(selected.size());
  pool.parallel_for(selected.size(), 16, [&](size_t begin, size_t end) {
    std::vector<PointletRecord> records;
    for (size_t s = begin; s < end; ++s) {
      const uint32_t index = selected[s];
      const PointletEntry& e = table[index];
      records.clear();
      cache.read(index, 0, counts[index], records);
      glm::dvec3 min, size;
      world_box(e, min, size);
      for (size_t r = 0; r < records.size(); ++r) {
        const glm::dvec3 p = z_up_to_y_up(cache.position(e, records[r]));
        const QuantizedPoint q = quantize(p, min, size);
        const uint64_t at = first[s] + r;
        out.coarse[at] = q.coarse;
        out.medium[at] = q.medium;
        out.fine[at] = q.fine;
        out.color[at] = records[r].rgba;
      }
      for (uint32_t b = 0; b < records.size(); b += kBatchPoints)
        batches[s].push_back({min, size, first[s] + b,
                              std::min<uint32_t>(kBatchPoints, uint32_t(records.size()) - b)});
    }
  });
  for (auto& list : batches) out.batches.insert(out.batches.end(), list.begin(), list.end());
  for (uint32_t i : selected) {
    glm::dvec3 min, size;
    world_box(table[i], min, size);
    out.world_bounds.extend(min);
    out.world_bounds.extend(min + size);
  }
  return out;
}

// A new selection when the view changed (in Queue: the target of this frame is known then).
void select_points(Registry& render) {
  auto& v = render.resource<VirtualCloudRender>();
  const auto& target = render.resource<RenderTarget>();
  const ExtractedCamera* extracted = first_extracted_camera(render);
  if (!extracted || !target.valid()) return;
  if (v.have_selection && same_view(v.selected_for, *extracted) && v.width == target.width &&
      v.height == target.height)
    return;
  gpu::Context& ctx = *render.resource<GpuContext>();
  auto& stats = render.resource<VirtualCloudStats>();
  if (!v.pointlets) {
    v.pointlets = std::make_unique<GpuPointlets>(upload_pointlets(ctx, *v.cache));
    v.lod = std::make_unique<PointletLodPipeline>(create_pointlet_lod_pipeline(ctx));
  }
  const Camera camera = to_camera(*extracted);
  auto t = Clock::now();
  const std::vector<uint32_t> counts = compute_pointlet_lod(
      ctx, *v.lod, *v.pointlets, camera, target.width, target.height, v.options.bucket);
  stats.lod_ms = ms_since(t);
  t = Clock::now();
  BatchedCloud batched = load_selection(*v.cache, counts, *v.pool);
  stats.load_ms = ms_since(t);
  stats.host_bytes = std::max<uint64_t>(
      stats.host_bytes, batched.point_count() * 16 + batched.batches.size() * sizeof(Batch));
  t = Clock::now();
  v.drawn.reset();  // the previous selection's buffers go before the new ones are made
  v.drawn = std::make_unique<GpuBatchedCloud>(upload_batched_cloud(ctx, batched));
  stats.upload_ms = ms_since(t);
  stats.gpu_bytes = v.drawn->bytes;
  stats.selected_points = batched.point_count();
  stats.visible_pointlets =
      uint32_t(std::count_if(counts.begin(), counts.end(), [](uint32_t c) { return c > 0; }));
  ++stats.selections;
  stats.bucket = v.options.bucket;
  v.have_selection = true;
  v.selected_for = *extracted;
  v.width = target.width;
  v.height = target.height;
}

void queue_virtual_cloud(Registry& render) {
  auto& fg = render.resource<FrameGraph>();
  if (!fg.active) return;
  select_points(render);
  auto& v = render.resource<VirtualCloudRender>();
  const auto& target = render.resource<RenderTarget>();
  const ExtractedCamera* extracted = first_extracted_camera(render);
  if (!extracted || !v.drawn) return;
  gpu::Context& ctx = *render.resource<GpuContext>();
  if (!v.raster || v.format != target.format) {
    v.raster =
        std::make_unique<ComputeRasterPipeline>(create_compute_raster_pipeline(ctx, target.format));
    v.format = target.format;
  }
  ComputeRasterOptions options;
  options.hqs = v.options.hqs;
  options.fill_radius = v.options.fill_radius;
  options.occlusion_beta = v.options.occlusion_beta;
  options.background = v.background;
  add_compute_raster_passes(fg.graph, *v.raster, *v.drawn, to_camera(*extracted), options,
                            target.width, target.height);
  auto& stats = render.resource<RenderStats>();
  stats.points_drawn += v.drawn->point_count;
  stats.points_total = v.cache->info().point_count;
}

void snapshot_virtual_stats(Registry& main) {
  Registry& render = *main.resource<RenderWorldRef>();
  main.insert_resource(render.resource<VirtualCloudStats>());
}

}  // namespace

void VirtualPointCloudPlugin::build(Engine& engine) {
  if (options.files.empty()) fail("VirtualPointCloudPlugin: no input");
  bool built = false;
  PointletBuildStats build_stats;
  auto cache = std::make_shared<const PointletCache>(
      open_pointlet_cache(options.files, options.cache_dir, options.build, &built, &build_stats));
  const PointletCacheInfo& info = cache->info();
  if (built)
    STIPPLE_INFO("{}: {} points in {} pointlets of {} ({:.1f} s)", cache->name(), info.point_count,
                 info.pointlet_count, info.pointlet_points, build_stats.seconds);
  else
    STIPPLE_INFO("{}: reused ({} points in {} pointlets)", cache->name(), info.point_count,
                 info.pointlet_count);
  engine.main().insert_resource(VirtualCloudCache{cache->name(), built, build_stats,
                                                  info.point_count, info.pointlet_count,
                                                  info.pointlet_points});
  SceneInfo scene;
  scene.world_bounds.extend(z_up_to_y_up(info.source_bounds.min));
  scene.world_bounds.extend(z_up_to_y_up(info.source_bounds.max));
  scene.points = info.point_count;
  scene.attributes = info.attributes;
  scene.name = options.files.front().filename().string();
  engine.main().insert_resource(scene);
  PointDrawSettings settings;
  settings.render = render;
  settings.compute = true;
  settings.hqs = options.hqs;
  settings.fill_radius = options.fill_radius;
  settings.occlusion_beta = options.occlusion_beta;
  engine.main().insert_resource(settings);
  engine.render().insert_resource(settings);

  VirtualCloudRender v;
  v.cache = cache;
  v.options = options;
  v.background = render.background;
  v.pool = std::make_unique<ThreadPool>(std::max(2u, std::thread::hardware_concurrency()));
  engine.render().insert_resource(std::move(v));
  engine.render().insert_resource(VirtualCloudStats{});
  engine.main().insert_resource(VirtualCloudStats{});
  engine.add_system(MainStage::Extract, snapshot_virtual_stats, "snapshot_virtual_stats");
  engine.add_system(RenderStage::Queue, queue_virtual_cloud, "queue_virtual_cloud");
}

}  // namespace stipple::pc
