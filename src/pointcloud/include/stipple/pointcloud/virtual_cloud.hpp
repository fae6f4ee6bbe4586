#pragma once
// VirtualPointCloudPlugin: LAS/LAZ/COPC of any size drawn from their pointlet cache (seed 002)
// in host and GPU memory bounded by the point bucket B, not by the file. The cache is built (or
// reused) in build(); whenever the camera changes, the render world runs the pointlets' LoD on
// the GPU (eqs. 2-3, B), reads the prefix of each visible pointlet that the LoD asks for from
// the cache with positional reads on a worker pool (a prefix of a shuffled pointlet is a uniform
// subsample), turns each into batches of the compute rasterizer (the pointlet's box, quantized
// positions) and uploads them; the compute rasterizer draws them.
//
// This is the first stage of the seed's system: selection is synchronous (the frame waits for
// its points) and nothing is kept between camera changes; the asynchronous virtual memory
// system (per-pointlet host buffers, over-fetch, GPU compaction), hole filling and the
// occlusion check come next.
#include <array>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include <glm/vec3.hpp>

#include "stipple/pointcloud/point_renderer.hpp"
#include "stipple/pointcloud/pointlet_lod.hpp"
#include "stipple/pointcloud/pointlets.hpp"

namespace stipple {
class Engine;
}

namespace stipple::pc {

struct VirtualCloudOptions {
  std::vector<std::filesystem::path> files;
  std::filesystem::path cache_dir;  // empty: beside the input (pointlet_cache_path)
  PointletBuildOptions build;
  uint64_t bucket = kDefaultPointBucket;  // B: the most points drawn in a frame
  bool hqs = false;
  uint64_t host_budget = uint64_t(1) << 30;  // bytes of loaded points kept on the host
  uint32_t fill_radius = 1;                  // hole filling (seed 002, III-D1); 0: off
  float occlusion_beta = 0.0f;               // occlusion check (eq. 4) threshold in radians; 0: off
};

// Main-world resource: the cache the plugin opened, and whether it had to build it.
struct VirtualCloudCache {
  std::string path;
  bool built = false;
  PointletBuildStats build;  // when built
  uint64_t points = 0, pointlets = 0, pointlet_points = 0;
};

// Render-world resource: what the last selection did; copied to the main world in every
// Extract (the panel shows it there, a frame late in pipelined mode).
struct VirtualCloudStats {
  uint64_t selections = 0;  // selections made (view changes, loads completed)
  uint64_t bucket = 0;      // B
  uint32_t visible_pointlets = 0;
  uint64_t desired_points = 0;                   // what the LoD asked for (<= B)
  uint64_t selected_points = 0;                  // what is drawn of it: the loaded part
  uint64_t host_bytes = 0, peak_host_bytes = 0;  // loaded points on the host
  uint64_t gpu_bytes = 0;                        // the uploaded batches
  uint32_t pending_loads = 0;
  uint64_t loads = 0, points_read = 0;  // load tasks done, points read from the cache
  bool settled = false;  // nothing loading and the drawn selection is what the LoD asked for
  double lod_ms = 0, load_ms = 0, upload_ms = 0;  // the last selection
};

// Main-world resource: waits for the loads in flight (a headless render waits until settled).
struct VirtualResidency;
struct VirtualCloudHandle {
  std::shared_ptr<VirtualResidency> residency;
};
// Blocks until a load completes, or `timeout_s` passed, or nothing is loading.
void wait_for_virtual_loads(const VirtualCloudHandle& handle, double timeout_s);

struct VirtualPointCloudPlugin {
  static constexpr std::string_view name = "VirtualPointCloudPlugin";
  static constexpr std::string_view description =
      "draws LAS/LAZ of any size from a pointlet cache: GPU LoD per camera, prefixes read "
      "from disk, compute rasterizer (point bucket B)";
  static constexpr std::array<std::string_view, 3> dependencies{"GpuPlugin", "RenderGraphPlugin",
                                                                "CameraPlugin"};
  VirtualCloudOptions options;
  PointRenderSettings render;  // background (the compute rasterizer draws RGB)
  void build(Engine& engine);
};

}  // namespace stipple::pc
