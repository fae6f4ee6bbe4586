#pragma once
// Draws a PointCloud with WebGPU: one interleaved vertex buffer per chunk, instanced quads,
// reverse-Z depth, camera-relative chunk offsets.
#include <memory>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "math/camera.hpp"
#include "pointcloud/point_cloud.hpp"
#include "renderer/gpu.hpp"
#include "renderer/gpu_timer.hpp"
#include "renderer/render_graph.hpp"

namespace stipple::pc {

struct GpuPointCloud {
  struct Chunk {
    gpu::Buffer vertices;
    uint32_t count = 0;
    glm::dvec3 origin{0.0};
  };
  std::vector<Chunk> chunks;
  uint64_t point_count = 0;
};

GpuPointCloud upload_point_cloud(gpu::Context& ctx, const PointCloud& cloud);

struct PointStyle {
  float point_size = 2.0f;  // pixels
  bool round = true;        // discs instead of squares (from 3 px up)
  glm::vec3 background{0.07f, 0.08f, 0.1f};
};

struct PointPipeline {
  gpu::ShaderModule shader;
  gpu::BindGroupLayout layout;
  gpu::PipelineLayout pipeline_layout;
  gpu::RenderPipeline pipeline;
  gpu::Buffer frame_uniforms;
  gpu::Buffer chunk_uniforms;  // one 256-byte-aligned slot per chunk (dynamic offsets)
  uint32_t chunk_stride = 256;
  uint32_t chunk_capacity = 0;
  gpu::BindGroup bind_group;
  WGPUTextureFormat depth_format = WGPUTextureFormat_Depth32Float;
  gpu::PassTimer timer;  // one pass: the point draw (draw_points)
};

PointPipeline create_point_pipeline(gpu::Context& ctx, WGPUTextureFormat color_format,
                                    WGPUTextureFormat depth_format);

// The point draw as render pass "points" of a graph: clears and draws into `color` (an imported
// writable texture). The depth buffer is a transient the pass creates, unless `create_depth` is
// off and `depth` names an imported writable texture.
struct PointPassTargets {
  std::string color = "color";
  std::string depth = "depth";
  bool create_depth = true;
};
void add_point_pass(gpu::RenderGraph& graph, PointPipeline& pipeline, const GpuPointCloud& cloud,
                    const Camera& camera, const PointStyle& style, uint32_t width, uint32_t height,
                    const PointPassTargets& targets = {});

// Records and submits one frame into the target views (a one-pass graph with both imported).
// With the pipeline's timer enabled, read_pass_times(ctx, pipeline.timer) gives the draw's GPU
// time afterwards.
void draw_points(gpu::Context& ctx, PointPipeline& pipeline, const GpuPointCloud& cloud,
                 const Camera& camera, const PointStyle& style, WGPUTextureView color,
                 WGPUTextureView depth, uint32_t width, uint32_t height);

// A point size in pixels that closes the gaps between neighbours for a surface scan seen from
// this camera: the mean spacing over the horizontal extent, projected at the target distance.
float auto_point_size(const PointCloud& cloud, const Camera& camera, uint32_t height);

}  // namespace stipple::pc
