#pragma once
// VirtualPointCloudPlugin: LAS/LAZ/COPC of any size drawn from their pointlet cache (seed 002)
// in host and GPU memory bounded by the point bucket B, not by the file. The cache is built (or
// reused) in build(). Whenever the camera changes, the render world runs the pointlets' LoD on
// the GPU (eqs. 2-3, B); load tasks on a worker pool grow each visible pointlet's host buffer
// to the prefix the LoD asks for (a prefix of a shuffled pointlet is a uniform subsample),
// reading the cache with positional reads, up to 25% more while the host budget allows, and
// unload what is not needed when the budget runs short. What the host holds of the selection
// goes to the GPU point store (point_store.hpp): the previous frame's points are kept, only
// new ones travel through mapped staging, and a compaction pass rebuilds the double-buffered
// point buffers. The compute rasterizer draws them, with hole filling and the occlusion check.
#include <array>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include <glm/vec3.hpp>

#include "stipple/math/camera.hpp"
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
  // When set, the whole process's resident memory stays under it: once the first frame has
  // made the GPU buffers (on a software GPU they are host memory too), what the process holds
  // besides the loaded points is measured, and the points get what is left of this (less a
  // margin for later growth), if that is below host_budget.
  uint64_t process_budget = 0;
  // The device's buffers are host memory (a CPU adapter: gpu::is_cpu_adapter, set by build()):
  // the process budget pays for them, and without gpu_budget the bucket is fitted to it.
  bool device_in_host = false;
  uint32_t fill_radius = 1;     // hole filling (seed 002, III-D1); 0: off
  float occlusion_beta = 0.0f;  // occlusion check (eq. 4) threshold in radians; 0: off
  // Device memory the point store and the pointlets may use; 0: what B needs. A bucket that
  // does not fit is lowered to what does (with a warning).
  uint64_t gpu_budget = 0;
  uint64_t staging_bytes = uint64_t(64) << 20;  // per staging slot (two): new points per frame
  // The viewer's first image at once: where the cache has to be built, build() starts the build
  // on another thread and returns, and what the scene drew first (an in-memory sample of the
  // input: PointCloudPlugin's PointCloudData) stays on screen meanwhile; once the build is done
  // (and the sample has been drawn at least once) the cloud opens at a frame's sync point and
  // takes the sample's place, with the camera and the style as they are then
  // (VirtualCacheProgress tells the front end). A current cache opens in build() as without it.
  bool build_in_background = false;
  // The selection (visits, loads, the store's plan and new points: milliseconds a frame while
  // the view moves over a large cloud) runs on a thread of its own, and frames go on drawing
  // the last selection until the next is done, so the frame rate does not wait for it (the
  // viewer, bench virtual). Off, each selection is made in the frame that needs it.
  bool async_selection = false;
};

// The point store's staging slots (each of staging_bytes): two, and three with async_selection,
// whose selection maps its slot as it starts, one commit after the last used it, while that
// frame may still be on the GPU (two frames in flight): the third keeps it from waiting.
inline uint32_t staging_slots(const VirtualCloudOptions& options) {
  return options.async_selection ? 3 : 2;
}

// Main-world resource (build_in_background): the background build of the cache, for the
// front end's status line and for knowing when the virtualized cloud is in.
struct VirtualCacheProgress {
  bool building = false;       // the sample is drawn while the cache builds
  uint32_t phase = 0;          // PointletBuildProgress::phase
  double fraction = 0;         // of the whole build, 0..1
  double seconds = 0;          // since the build started
  uint64_t frames_before = 0;  // frames drawn before the virtualized cloud took over
  bool switched = false;       // the virtualized cloud replaced the sample
};
// "reading and sorting 42%" for a phase and fraction (the viewer's panel).
std::string describe_cache_progress(const VirtualCacheProgress& progress);

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
  uint64_t host_budget = 0;    // what the loaded points may take (after process_budget)
  uint64_t process_bytes = 0;  // the process's resident memory at the last selection
  uint64_t gpu_bytes = 0;      // device memory: point store and pointlet buffers
  uint64_t staging_bytes = 0;  // mapped host memory for the transfers
  uint64_t kept_points = 0, new_points = 0;  // the last update: kept on the GPU, transferred
  uint32_t pending_loads = 0;
  uint64_t loads = 0, points_read = 0;  // load tasks done, points read from the cache
  bool settled = false;  // nothing loading and the drawn selection is what the LoD asked for
  double lod_ms = 0, upload_ms = 0;  // CPU ms of the last selection: LoD (with its readback),
                                     // planning and writing new points into staging
  double residency_ms = 0;           // deciding what to load and unload, queueing the loads
  double staging_wait_ms = 0, fresh_write_ms = 0;  // parts of upload_ms
  double select_ms = 0;          // CPU ms of this frame's selection work (all of it)
  double trim_ms = 0;            // CPU ms spent handing freed heap memory back (summed)
  uint64_t heap_free_bytes = 0;  // free bytes held in malloc's arenas (glibc), every 64th selection
  // GPU ms of the last frame in the five stages of seed 002, Fig. 15 (kStageNames).
  std::array<double, 5> stage_ms{};
  uint32_t touched_pointlets = 0;  // the last selection: pointlets whose wanted prefix it revisited
  double select_cpu_ms = 0;        // select_ms as the thread's CPU time (0 where unavailable)
  double async_select_ms = 0;      // async_selection: wall ms of the last selection on its thread
};
inline constexpr std::array<std::string_view, 5> kStageNames{"lod", "compaction", "projection",
                                                             "resolve", "fill"};

// What the loaded points may take under a process budget: what the process holds besides them
// (resident - loaded) and a margin (5%, at least 32 MiB) for later growth are left out; never
// more than host_budget.
uint64_t points_budget(uint64_t process_budget, uint64_t resident, uint64_t loaded,
                       uint64_t host_budget);
// The least process budget that leaves `need` bytes after points_budget's margin. A budget
// under the baseline (what the process holds before points load), the staging and room for
// kMinimumBudgetPoints points (on a CPU adapter, on the device too) is an error naming it.
uint64_t minimum_process_budget(uint64_t need);
inline constexpr uint64_t kMinimumBudgetPoints = uint64_t(1) << 18;

// Main-world resource: waits for the loads in flight (a headless render waits until settled).
struct VirtualResidency;
struct VirtualCloudHandle {
  std::shared_ptr<VirtualResidency> residency;
};
// Blocks until a load completes, or `timeout_s` passed, or nothing is loading.
void wait_for_virtual_loads(const VirtualCloudHandle& handle, double timeout_s);
// Adds the cache's points to a view fit (world space), as fit_chunks does for a cloud in
// memory, so that both paths frame the same data alike: pointlets are taken outermost first and
// those whose boxes cannot widen the fit are not read, so few of a large cache's points are.
void fit_virtual_cloud(ViewFit& fit, const VirtualCloudHandle& handle);

struct VirtualPointCloudPlugin {
  static constexpr std::string_view name = "VirtualPointCloudPlugin";
  static constexpr std::string_view description =
      "draws LAS/LAZ of any size from a pointlet cache: GPU LoD per camera, prefixes read "
      "from disk, compute rasterizer (point bucket B)";
  static constexpr std::array<std::string_view, 3> dependencies{"GpuPlugin", "RenderGraphPlugin",
                                                                "CameraPlugin"};
  VirtualCloudOptions options;
  PointRenderSettings render;  // colour, point size, background, eye-dome lighting
  void build(Engine& engine);
};

}  // namespace stipple::pc
