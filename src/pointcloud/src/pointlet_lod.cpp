#include "stipple/pointcloud/pointlet_lod.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>

#include <glm/geometric.hpp>
#include <glm/gtc/type_ptr.hpp>

#include "stipple/core/error.hpp"
#include "stipple/renderer/shader_preprocessor.hpp"

namespace stipple::pc {
namespace {

constexpr uint32_t kWorkgroup = 256;

// shaders/pointlet_lod.wgsl's Params.
struct Params {
  float view_proj[16];
  float offset[3];
  uint32_t count;
  float viewport[2];
  float bucket;
  uint32_t partials;
};
static_assert(sizeof(Params) == 96);

glm::mat4 lod_view_proj(const Camera& camera, uint32_t width, uint32_t height) {
  return glm::mat4(camera.projection(double(width) / double(height)) * camera.view_rotation());
}

// The shader's weight_of, in the same float arithmetic.
float weight_of(const PointletBox& b, const glm::mat4& vp, const glm::vec3& offset,
                const glm::vec2& viewport) {
  const glm::vec3 lo = glm::vec3(b.lo[0], b.lo[1], b.lo[2]) + offset;
  const glm::vec3 hi = glm::vec3(b.hi[0], b.hi[1], b.hi[2]) + offset;
  bool out_l = true, out_r = true, out_b = true, out_t = true, out_n = true;
  for (int i = 0; i < 8; ++i) {
    const glm::vec3 corner(i & 1 ? hi.x : lo.x, i & 2 ? hi.y : lo.y, i & 4 ? hi.z : lo.z);
    const glm::vec4 c = vp * glm::vec4(corner, 1.0f);
    out_l = out_l && c.x < -c.w;
    out_r = out_r && c.x > c.w;
    out_b = out_b && c.y < -c.w;
    out_t = out_t && c.y > c.w;
    out_n = out_n && c.z > c.w;
  }
  if (out_l || out_r || out_b || out_t || out_n) return 0.0f;
  const glm::vec4 center = vp * glm::vec4((lo + hi) * 0.5f, 1.0f);
  const glm::vec4 corner = vp * glm::vec4(hi, 1.0f);
  float projected = glm::length(viewport);
  if (center.w > 0.0f && corner.w > 0.0f) {
    const glm::vec2 half_view = viewport * 0.5f;
    projected = glm::length(half_view * (glm::vec2(center) / center.w) -
                            half_view * (glm::vec2(corner) / corner.w));
  }
  const float r = std::max(b.lo[3], 1e-6f);
  return projected / (r * r);
}

}  // namespace

std::vector<PointletBox> pointlet_boxes(const std::vector<PointletEntry>& table,
                                        const glm::dvec3& origin) {
  // A pointlet of one point (every pointlet when the cloud has fewer than twice --pointlets
  // points: k = 1) or of coincident points has an empty box: eq. 2 then gives 0 / 0, every such
  // pointlet got no points, and a whole image stayed empty. Boxes whose half diagonal is under
  // a floor grow around their centre to it; the floor is an eighth of the spacing pointlets
  // would have tiling the cloud's extent as a surface, far under any real pointlet's size, so
  // the others keep the seed's weights exactly.
  std::vector<Aabb> world(table.size());
  Aabb all;
  for (size_t i = 0; i < table.size(); ++i) {
    world[i] = pointlet_world_box(table[i]);
    all.extend(world[i].min);
    all.extend(world[i].max);
  }
  // At least a millimetre (the frame is metric: geographic input goes to a local frame), for a
  // cloud of one point or of coincident points, whose extent is zero.
  const double floor_half_diagonal =
      table.empty() ? 0.0
                    : std::max(1e-3, 0.125 * 0.5 * glm::length(all.max - all.min) /
                                         std::sqrt(double(table.size())));
  std::vector<PointletBox> boxes(table.size());
  for (size_t i = 0; i < table.size(); ++i) {
    glm::dvec3 lo = world[i].min - origin, hi = world[i].max - origin;
    double half_diagonal = 0.5 * glm::length(hi - lo);
    if (half_diagonal < floor_half_diagonal) {
      const glm::dvec3 centre = (lo + hi) * 0.5;
      const glm::dvec3 half =
          glm::max((hi - lo) * 0.5, glm::dvec3(floor_half_diagonal / std::sqrt(3.0)));
      lo = centre - half;
      hi = centre + half;
      half_diagonal = glm::length(half);
    }
    boxes[i] = {{float(lo.x), float(lo.y), float(lo.z), float(half_diagonal)},
                {float(hi.x), float(hi.y), float(hi.z), 0.0f}};
  }
  return boxes;
}

GpuPointlets upload_pointlets(gpu::Context& ctx, const PointletCache& cache) {
  GpuPointlets g;
  const auto& table = cache.pointlets();
  g.count = uint32_t(table.size());
  g.origin = z_up_to_y_up(cache.info().source_bounds.center());
  g.partials = (g.count + kWorkgroup - 1) / kWorkgroup;
  const auto boxes = pointlet_boxes(table, g.origin);
  std::vector<uint32_t> sizes(2 * size_t(g.count));
  for (size_t i = 0; i < table.size(); ++i) {
    sizes[2 * i] = sizes[2 * i + 1] = table[i].count;
    g.point_counts.push_back(table[i].count);
  }
  const auto storage = WGPUBufferUsage_Storage | WGPUBufferUsage_CopyDst;
  g.params =
      gpu::create_buffer(ctx, sizeof(Params), WGPUBufferUsage_Uniform | WGPUBufferUsage_CopyDst,
                         "pointlet-lod-params");
  g.boxes = gpu::create_buffer(ctx, std::max<size_t>(1, boxes.size()) * sizeof(PointletBox),
                               storage, "pointlet-boxes", boxes.data());
  g.sizes = gpu::create_buffer(ctx, std::max<size_t>(1, sizes.size()) * 4, storage,
                               "pointlet-sizes", sizes.data());
  g.weights = gpu::create_buffer(ctx, std::max<uint64_t>(1, g.count) * 4, WGPUBufferUsage_Storage,
                                 "pointlet-weights");
  g.partial_sums = gpu::create_buffer(ctx, (uint64_t(g.partials) + 1) * 4, WGPUBufferUsage_Storage,
                                      "pointlet-partial-sums");
  g.counts =
      gpu::create_buffer(ctx, std::max<uint64_t>(1, g.count) * 4,
                         WGPUBufferUsage_Storage | WGPUBufferUsage_CopySrc, "pointlet-counts");
  const uint64_t n = std::max<uint64_t>(1, g.count);
  g.bytes = sizeof(Params) + n * sizeof(PointletBox) + n * 8 + n * 4 + (g.partials + 1) * 4 + n * 4;
  ctx.check("uploading pointlets");
  return g;
}

void set_loaded_points(gpu::Context& ctx, GpuPointlets& g, const std::vector<uint32_t>& loaded) {
  if (loaded.size() != g.count)
    fail("set_loaded_points: {} counts for {} pointlets", loaded.size(), g.count);
  std::vector<uint32_t> pairs(2 * size_t(g.count));
  for (size_t i = 0; i < loaded.size(); ++i) pairs[2 * i] = g.point_counts[i];
  for (size_t i = 0; i < loaded.size(); ++i) pairs[2 * i + 1] = loaded[i];
  gpu::write_buffer(ctx, g.sizes.get(), 0, pairs.data(), pairs.size() * 4);
}

PointletLodPipeline create_pointlet_lod_pipeline(gpu::Context& ctx) {
  gpu::ShaderModule shader = gpu::create_shader_from_file(ctx, "pointlet_lod.wgsl");
  PointletLodPipeline p;
  using B = gpu::BufferBinding;
  p.layout = gpu::create_compute_layout(
      ctx, {B::Uniform, B::ReadOnlyStorage, B::ReadOnlyStorage, B::Storage, B::Storage, B::Storage},
      "pointlet-lod");
  p.pipeline_layout = gpu::create_pipeline_layout(ctx, {p.layout.get()});
  p.weights = gpu::create_compute_pipeline(ctx, shader.get(), "weights_main",
                                           p.pipeline_layout.get(), "pointlet-weights");
  p.total = gpu::create_compute_pipeline(ctx, shader.get(), "total_main", p.pipeline_layout.get(),
                                         "pointlet-total");
  p.counts = gpu::create_compute_pipeline(ctx, shader.get(), "counts_main", p.pipeline_layout.get(),
                                          "pointlet-counts");
  ctx.check("creating the pointlet LoD pipelines");
  return p;
}

void add_pointlet_lod_passes(gpu::RenderGraph& graph, PointletLodPipeline& p, GpuPointlets& g,
                             const Camera& camera, uint32_t width, uint32_t height,
                             uint64_t bucket) {
  Params params{};
  const glm::mat4 vp = lod_view_proj(camera, width, height);
  std::memcpy(params.view_proj, glm::value_ptr(vp), sizeof(params.view_proj));
  const glm::vec3 offset(g.origin - camera.position);
  params.offset[0] = offset.x;
  params.offset[1] = offset.y;
  params.offset[2] = offset.z;
  params.count = g.count;
  params.viewport[0] = float(width);
  params.viewport[1] = float(height);
  params.bucket = float(bucket);
  params.partials = g.partials;
  // The three entry points bind the same resources; each pipeline's layout is its own.
  auto make_group = [&g, &p](gpu::Context& ctx) {
    return gpu::create_bind_group(
        ctx, p.layout.get(),
        {gpu::bind_buffer(0, g.params.get()), gpu::bind_buffer(1, g.boxes.get()),
         gpu::bind_buffer(2, g.sizes.get()), gpu::bind_buffer(3, g.weights.get()),
         gpu::bind_buffer(4, g.partial_sums.get()), gpu::bind_buffer(5, g.counts.get())});
  };
  graph.import_buffer("pointlet-counts", g.counts.get(),
                      {uint64_t(std::max<uint32_t>(1, g.count)) * 4, WGPUBufferUsage_Storage},
                      gpu::Access::Writable);
  graph
      .add_pass("pointlet-lod", gpu::PassKind::Compute,
                [&p, &g, params, make_group](gpu::PassContext& pc) {
                  gpu::Context& ctx = pc.gpu();
                  gpu::write_buffer(ctx, g.params.get(), 0, params);
                  if (g.count == 0) return;
                  auto group = make_group(ctx);
                  // One compute pass: dispatches in a pass see each other's storage writes.
                  auto pass = pc.begin_compute_pass();
                  gpu::dispatch(pass.get(), p.weights.get(), {group.get()}, g.partials);
                  gpu::dispatch(pass.get(), p.total.get(), {group.get()}, 1);
                  gpu::dispatch(pass.get(), p.counts.get(), {group.get()}, g.partials);
                  wgpuComputePassEncoderEnd(pass.get());
                })
      .write("pointlet-counts");
}

std::vector<uint32_t> compute_pointlet_lod(gpu::Context& ctx, PointletLodPipeline& p,
                                           GpuPointlets& g, const Camera& camera, uint32_t width,
                                           uint32_t height, uint64_t bucket, double* gpu_ms) {
  gpu::RenderGraph graph;
  add_pointlet_lod_passes(graph, p, g, camera, width, height, bucket);
  gpu::TransientPool pool;
  if (gpu_ms && !p.timer_created) {
    p.timer = gpu::create_pass_timer(ctx, 1);
    p.timer_created = true;
  }
  graph.execute(ctx, pool, gpu_ms ? &p.timer : nullptr);
  ctx.check("pointlet LoD");
  std::vector<uint32_t> counts(g.count);
  gpu::read_back(ctx, g.readback, g.counts.get(), 0, uint64_t(g.count) * 4, counts.data());
  if (gpu_ms) {
    const auto times = graph.read_pass_times(ctx, p.timer);
    auto it = times.find("pointlet-lod");
    *gpu_ms = it == times.end() ? 0.0 : it->second;
  }
  return counts;
}

std::vector<uint32_t> pointlet_lod_cpu(const std::vector<PointletBox>& boxes,
                                       const std::vector<uint32_t>& sizes,
                                       const std::vector<uint32_t>& loaded,
                                       const glm::dvec3& origin, const Camera& camera,
                                       uint32_t width, uint32_t height, uint64_t bucket,
                                       std::vector<float>* weights_out) {
  const glm::mat4 vp = lod_view_proj(camera, width, height);
  const glm::vec3 offset(origin - camera.position);
  const glm::vec2 viewport{float(width), float(height)};
  std::vector<float> w(boxes.size());
  double total = 0;
  for (size_t i = 0; i < boxes.size(); ++i) {
    w[i] = weight_of(boxes[i], vp, offset, viewport);
    total += w[i];
  }
  std::vector<uint32_t> counts(boxes.size(), 0);
  const float total_f = float(total), bucket_f = float(bucket);
  for (size_t i = 0; i < boxes.size(); ++i) {
    uint32_t n = 0;
    if (total_f > 0) n = uint32_t(std::min(std::floor(w[i] / total_f * bucket_f), 4294967040.0f));
    counts[i] = std::min({n, sizes[i], loaded[i]});
  }
  if (weights_out) *weights_out = std::move(w);
  return counts;
}

}  // namespace stipple::pc
