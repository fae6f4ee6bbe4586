#pragma once
// The level of detail of pointlets (seed 002, III-B), per frame on the GPU: frustum culling of
// the pointlets' boxes, importance l_i (eq. 2) with gamma_i (eq. 3), normalised over the visible
// pointlets and multiplied by the point bucket B: how many points each pointlet draws, capped
// by its size and by what is loaded (shaders/pointlet_lod.wgsl). pointlet_lod_cpu is the same
// computation on the CPU, in the same float arithmetic, for tests.
#include <cstdint>
#include <vector>

#include <glm/vec3.hpp>

#include "stipple/math/camera.hpp"
#include "stipple/pointcloud/pointlets.hpp"
#include "stipple/renderer/gpu.hpp"
#include "stipple/renderer/gpu_timer.hpp"
#include "stipple/renderer/render_graph.hpp"
#include "stipple/renderer/staging.hpp"

namespace stipple::pc {

inline constexpr uint64_t kDefaultPointBucket = 25'000'000;  // B

// The pointlets' boxes on the GPU (static for the cache's life), in world space (Y up)
// relative to `origin`, the cache's centre; their sizes and loaded counts; the LoD's outputs.
struct GpuPointlets {
  uint32_t count = 0;
  glm::dvec3 origin{0.0};
  gpu::Buffer params, boxes, sizes, weights, partial_sums, counts;
  uint32_t partials = 0;
  std::vector<uint32_t> point_counts;  // points per pointlet (the CPU's copy)
  gpu::ReadbackBuffer readback;        // the counts come back through it
  uint64_t bytes = 0;                  // device memory of the buffers above
};

// The boxes a cache's table gives, as uploaded (min, half diagonal, max; relative to origin).
struct PointletBox {
  float lo[4], hi[4];
};
std::vector<PointletBox> pointlet_boxes(const std::vector<PointletEntry>& table,
                                        const glm::dvec3& origin);

GpuPointlets upload_pointlets(gpu::Context& ctx, const PointletCache& cache);
// Loaded points per pointlet (the virtual memory system's state); every point by default.
void set_loaded_points(gpu::Context& ctx, GpuPointlets& pointlets,
                       const std::vector<uint32_t>& loaded);

struct PointletLodPipeline {
  gpu::BindGroupLayout layout;  // shared by the three entry points
  gpu::PipelineLayout pipeline_layout;
  gpu::ComputePipeline weights, total, counts;
  gpu::PassTimer timer;  // when compute_pointlet_lod is asked for GPU time
  bool timer_created = false;
};
PointletLodPipeline create_pointlet_lod_pipeline(gpu::Context& ctx);

// The three LoD passes (pointlet-weights, pointlet-total, pointlet-counts) into the graph; the
// counts land in pointlets.counts. The pipeline and pointlets must outlive the graph's run.
void add_pointlet_lod_passes(gpu::RenderGraph& graph, PointletLodPipeline& pipeline,
                             GpuPointlets& pointlets, const Camera& camera, uint32_t width,
                             uint32_t height, uint64_t bucket = kDefaultPointBucket);
// Runs them once and reads the counts back (blocks); `gpu_ms`, when given, gets their GPU time.
std::vector<uint32_t> compute_pointlet_lod(gpu::Context& ctx, PointletLodPipeline& pipeline,
                                           GpuPointlets& pointlets, const Camera& camera,
                                           uint32_t width, uint32_t height,
                                           uint64_t bucket = kDefaultPointBucket,
                                           double* gpu_ms = nullptr);

// The same on the CPU: per-pointlet counts (0 for culled pointlets), and the weights w_i.
std::vector<uint32_t> pointlet_lod_cpu(const std::vector<PointletBox>& boxes,
                                       const std::vector<uint32_t>& sizes,
                                       const std::vector<uint32_t>& loaded,
                                       const glm::dvec3& origin, const Camera& camera,
                                       uint32_t width, uint32_t height, uint64_t bucket,
                                       std::vector<float>* weights = nullptr);

}  // namespace stipple::pc
