#include "stipple/splats/splat_plugin.hpp"

#include <algorithm>
#include <limits>
#include <string>

#include <glm/mat3x3.hpp>

#include "stipple/engine/camera.hpp"
#include "stipple/engine/engine.hpp"
#include "stipple/engine/render_plugins.hpp"
#include "stipple/engine/sync.hpp"
#include "stipple/engine/transform.hpp"
#include "stipple/splats/splats.hpp"

namespace stipple::splats {
namespace {

// Render-world component on a set's twin.
struct RenderSplats {
  std::shared_ptr<const io::SplatSet> set;
  std::vector<std::shared_ptr<const io::SplatSet>> parts;  // SplatData::parts
  glm::dmat4 parts_transform{1.0};
  SplatPartCache part_cache;  // the parts uploaded (kept while the main world holds them)
  uint64_t generation = 0;
  bool taken = false;           // set, parts and generation taken from the main world once
  glm::dvec3 translation{0.0};  // from the entity's GlobalTransform
  uint64_t uploaded_generation = std::numeric_limits<uint64_t>::max();
  // The passes read it when the graph executes (Draw): boxed, its address must not move.
  std::unique_ptr<GpuSplats> gpu;
};

// Render-world resource: the pipelines for the current target format.
struct SplatPipelineCache {
  std::unique_ptr<SplatPipelines> pipelines;
  WGPUTextureFormat format = WGPUTextureFormat_Undefined;
};

void extract_splats(Registry& main) {
  Registry& render = *main.resource<RenderWorldRef>();
  render.insert_resource(main.resource<SplatDrawSettings>());
  main.view<SplatData, RenderEntity>().each(
      [&](Entity e, const SplatData& data, const RenderEntity& twin) {
        auto* r = render.try_get<RenderSplats>(twin.entity);
        if (!r) r = &render.emplace<RenderSplats>(twin.entity);
        if (!r->taken || r->generation != data.generation) {
          r->taken = true;
          r->set = data.set;
          r->parts = data.parts;
          r->parts_transform = data.parts_transform;
          r->generation = data.generation;
        }
        const auto* global = main.try_get<GlobalTransform>(e);
        r->translation = global ? global->translation() : glm::dvec3(0.0);
      });
}

void upload_splat_sets(Registry& render) {
  gpu::Context& ctx = *render.resource<GpuContext>();
  render.view<RenderSplats>().each([&](RenderSplats& r) {
    if (r.uploaded_generation == r.generation) return;
    if (r.set)
      r.gpu = std::make_unique<GpuSplats>(upload_splats(ctx, *r.set));
    else  // parts, perhaps none (a stream that draws nothing now)
      compose_splats(ctx, r.part_cache, r.gpu, r.parts, r.parts_transform);
    r.uploaded_generation = r.generation;
  });
}

// Whether an earlier pass of the frame made or wrote `name`.
bool graph_has(const gpu::RenderGraph& graph, const std::string& name) {
  for (const auto& pass : graph.passes()) {
    if (std::find(pass.creates.begin(), pass.creates.end(), name) != pass.creates.end() ||
        std::find(pass.writes.begin(), pass.writes.end(), name) != pass.writes.end())
      return true;
  }
  return false;
}

void queue_splats(Registry& render) {
  auto& fg = render.resource<FrameGraph>();
  if (!fg.active) return;
  const auto& target = render.resource<RenderTarget>();
  const ExtractedCamera* extracted = first_extracted_camera(render);
  if (!extracted) return;
  auto& cache = render.resource<SplatPipelineCache>();
  const auto& settings = render.resource<SplatDrawSettings>();
  gpu::Context& ctx = *render.resource<GpuContext>();
  bool any = false;
  render.view<RenderSplats>().each([&](RenderSplats& r) { any = any || (r.gpu && r.gpu->count); });
  if (!any) return;
  if (cache.format != target.format || !cache.pipelines) {
    cache.pipelines = std::make_unique<SplatPipelines>(create_splat_pipelines(ctx, target.format));
    cache.format = target.format;
  }
  // Splats alone: nothing has drawn the target yet.
  if (!graph_has(fg.graph, "color")) {
    const glm::vec3 bg = settings.background;
    fg.graph
        .add_pass("splat-clear", gpu::PassKind::Render,
                  [bg](gpu::PassContext& pc) {
                    WGPURenderPassColorAttachment color = WGPU_RENDER_PASS_COLOR_ATTACHMENT_INIT;
                    color.view = pc.view("color");
                    color.loadOp = WGPULoadOp_Clear;
                    color.storeOp = WGPUStoreOp_Store;
                    color.clearValue = {bg.r, bg.g, bg.b, 1.0};
                    WGPURenderPassDescriptor desc = WGPU_RENDER_PASS_DESCRIPTOR_INIT;
                    desc.colorAttachmentCount = 1;
                    desc.colorAttachments = &color;
                    auto pass = pc.begin_render_pass(desc);
                    wgpuRenderPassEncoderEnd(pass.get());
                  })
        .write("color");
  }
  SplatPassTargets targets;
  targets.rasterizer = settings.rasterizer.value_or(default_splat_rasterizer(ctx));
  if (!settings.depth_test || !graph_has(fg.graph, "depth")) targets.depth.clear();
  uint32_t index = 0;
  render.view<RenderSplats>().each([&](RenderSplats& r) {
    if (!r.gpu || r.gpu->count == 0 || r.uploaded_generation != r.generation) return;
    Camera camera = to_camera(*extracted);
    camera.position -= r.translation;
    targets.name = index == 0 ? "splat" : "splat" + std::to_string(index);
    if (targets.rasterizer == SplatRasterizer::Tiles) {
      // Earlier frames' tile pair counts that have come back grow the buffers before this one
      // (never waited for); a kept frame waits for its own and is drawn again if it lost pairs.
      settle_tile_pairs(ctx, *r.gpu, false);
      fg.redraw_checks.push_back(
          [g = r.gpu.get()](gpu::Context& c) { return settle_tile_pairs(c, *g, true); });
    }
    add_splat_passes(fg.graph, *cache.pipelines, *r.gpu, camera, target.width, target.height,
                     targets);
    ++index;
  });
}

}  // namespace

Aabb splat_bounds(const io::SplatSet& set) {
  Aabb box;
  const glm::dmat3 linear(set.transform);
  const glm::dvec3 translation(set.transform[3]);
  for (const auto& p : set.positions) box.extend(linear * glm::dvec3(p) + translation);
  return box;
}

bool splat_frames_incomplete(Engine& engine) {
  engine.wait_for_render();
  Registry& render = engine.render();
  const auto* gpu = render.try_resource<GpuContext>();
  if (!gpu) return false;
  bool grew = false;
  render.view<RenderSplats>().each([&](RenderSplats& r) {
    if (r.gpu) grew = settle_tile_pairs(**gpu, *r.gpu, false) || grew;
  });
  return grew;
}

void SplatPlugin::build(Engine& engine) {
  Registry& main = engine.main();
  uint64_t generation = 0;
  for (const auto& set : sets) {
    if (!set) continue;
    Entity e = main.create();
    SplatData data;
    data.set = set;
    data.generation = generation++;
    main.emplace<SplatData>(e, std::move(data));
    main.emplace<Transform>(e);
    main.emplace<SyncTo<RenderWorldTag>>(e);
  }
  main.insert_resource(settings);
  engine.render().insert_resource(settings);
  engine.render().insert_resource(SplatPipelineCache{});
  engine.add_system(MainStage::Extract, extract_splats, "extract_splats");
  engine.add_system(RenderStage::Prepare, upload_splat_sets, "upload_splats");
  engine.add_system(RenderStage::Queue, queue_splats, "queue_splats");
}

}  // namespace stipple::splats
