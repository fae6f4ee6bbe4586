#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <utility>
#include <vector>

#include "stipple/core/memory.hpp"
#include "stipple/engine/engine.hpp"
#include "stipple/pointcloud/point_cloud.hpp"
#include "stipple/pointcloud/point_cloud_plugin.hpp"
#include "stipple/pointcloud/pointlets.hpp"
#include "stipple/pointcloud/virtual_cloud.hpp"
#include "virtual_scene.hpp"

namespace stipple::scene {

namespace {

// How the cache is built under a host budget: the sort's runs take at most half of it.
pc::PointletBuildOptions build_options(const SceneOptions& options, uint64_t budget) {
  pc::PointletBuildOptions build;
  build.pointlets = options.pointlets;
  build.memory_budget = std::min<uint64_t>(budget / 2, uint64_t(4) << 30);
  return build;
}

// The sample drawn while the cache builds: about options.progressive_points points read across
// the inputs, in memory, drawn by the compute rasterizer with the virtualized path's hole
// filling, so that the switch to the cache changes the density, not the look.
void add_cache_sample(Engine& engine, const ScenePlan& plan) {
  const SceneOptions& options = plan.options;
  const auto start = std::chrono::steady_clock::now();
  pc::LoadOptions load;
  load.sample = options.progressive_points;
  load.chunk_points = options.chunk_points;
  load.progress = false;
  load.keep_extras = options.keep_extras || options.render.filter.needs_extras();
  const std::vector<std::filesystem::path> files(options.inputs.begin(), options.inputs.end());
  pc::PointCloudPlugin points;
  points.inputs.points = std::make_shared<const pc::PointCloud>(pc::load_point_cloud(files, load));
  points.settings.render = options.render;
  points.settings.compute = true;
  points.settings.hqs = options.hqs;
  points.settings.fill_radius = options.fill_radius < 0 ? 1u : uint32_t(options.fill_radius);
  points.settings.occlusion_beta = options.occlusion_beta;
  std::printf("first image: %llu points read across the input in %.2f s\n",
              static_cast<unsigned long long>(points.inputs.points->point_count),
              std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  engine.add_plugin(std::move(points));
}

}  // namespace

void build_virtual_cache(const SceneOptions& options, uint64_t host_budget) {
  pc::PointletBuildOptions build = build_options(options, host_budget);
  build.progress = false;
  const std::vector<std::filesystem::path> files(options.inputs.begin(), options.inputs.end());
  pc::open_pointlet_cache(files, options.cache_dir, build);
}

void add_virtual_scene(Engine& engine, const ScenePlan& plan) {
  const SceneOptions& options = plan.options;
  std::printf("drawing from a pointlet cache (%s)%s\n", plan.source.virtual_reason.c_str(),
              options.renderer == Renderer::Compute
                  ? ""
                  : "; the virtualized path draws with the compute rasterizer");
  pc::VirtualPointCloudPlugin v;
  v.options.files.assign(options.inputs.begin(), options.inputs.end());
  const bool progressive =
      options.progressive_points > 0 &&
      !pc::pointlet_cache_current(v.options.files, options.cache_dir,
                                  build_options(options, plan.source.host_budget));
  if (progressive) add_cache_sample(engine, plan);
  v.options.cache_dir = options.cache_dir;
  const uint64_t budget = plan.source.host_budget;
  v.options.build = build_options(options, budget);
  // The host budget is the process's: the loaded points get what the mapped staging slots
  // (two, three with the selection on its own thread) leave, and once the first frame has run, at
  // most what the rest of the process (libraries, driver, tables, and the GPU buffers on a software
  // GPU) leaves of it.
  v.options.async_selection = options.async_selection;
  v.options.staging_bytes =
      std::clamp<uint64_t>(budget / 16, uint64_t(1) << 20, uint64_t(64) << 20);
  v.options.host_budget = budget > 4 * v.options.staging_bytes
                              ? budget - pc::staging_slots(v.options) * v.options.staging_bytes
                              : budget / 2;
  v.options.process_budget = budget;
  if (!options.gpu_memory.empty()) v.options.gpu_budget = parse_size(options.gpu_memory);
  v.options.bucket = options.bucket;
  v.options.hqs = options.hqs;
  v.options.fill_radius = options.fill_radius < 0 ? 1u : uint32_t(options.fill_radius);
  v.options.occlusion_beta = options.occlusion_beta;
  v.render = options.render;
  v.options.build_in_background = progressive;
  engine.add_plugin(std::move(v));
  if (progressive) {
    std::printf("building the pointlet cache in the background; until then the sample is drawn\n");
    std::fflush(stdout);
    // Says once when the cache took the sample's place (tests read it).
    engine.add_system(
        MainStage::Update,
        [said = false](Registry& main) mutable {
          const auto* progress = main.try_resource<pc::VirtualCacheProgress>();
          if (said || !progress || !progress->switched) return;
          said = true;
          const auto& c = main.resource<pc::VirtualCloudCache>();
          std::printf(
              "built %s: %llu points in %llu pointlets of %llu in %.2f s; drawn from it after "
              "%llu frames of the sample\n",
              c.path.c_str(), static_cast<unsigned long long>(c.points),
              static_cast<unsigned long long>(c.pointlets),
              static_cast<unsigned long long>(c.pointlet_points), c.build.seconds,
              static_cast<unsigned long long>(progress->frames_before));
          std::printf("%s\n", pc::describe_build_phases(c.build).c_str());
          std::fflush(stdout);
        },
        "report_virtual_cache");
    return;
  }
  const auto& c = engine.main().resource<pc::VirtualCloudCache>();
  if (c.built) {
    std::printf("built %s: %llu points in %llu pointlets of %llu in %.2f s\n", c.path.c_str(),
                static_cast<unsigned long long>(c.points),
                static_cast<unsigned long long>(c.pointlets),
                static_cast<unsigned long long>(c.pointlet_points), c.build.seconds);
    std::printf("%s\n", pc::describe_build_phases(c.build).c_str());
  } else {
    std::printf("reused %s (the input is unchanged)\n", c.path.c_str());
  }
}

void fit_virtual_scene(ViewFit& fit, Registry& main) {
  if (const auto* handle = main.try_resource<pc::VirtualCloudHandle>())
    pc::fit_virtual_cloud(fit, *handle);
}

}  // namespace stipple::scene
