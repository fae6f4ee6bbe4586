#include "stipple/engine/render_plugins.hpp"

#include <chrono>
#include <sstream>
#include <utility>

#include "stipple/core/atomic_file.hpp"
#include "stipple/core/error.hpp"
#include "stipple/core/log.hpp"
#include "stipple/engine/engine.hpp"
#include "stipple/engine/viewport.hpp"
#include "stipple/renderer/png.hpp"

namespace stipple {
namespace {

double now_seconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

void start_render_frame(Registry& render) {
  auto& stats = render.resource<RenderStats>();
  stats.frame_start = now_seconds();
  stats.points_drawn = 0;
  render.resource<FrameGraph>().executed = false;
}

// After every Prepare system of every plugin: the target is known.
void begin_frame_graph(Registry& render) {
  auto& fg = render.resource<FrameGraph>();
  fg.graph = gpu::RenderGraph{};
  const auto* target = render.try_resource<RenderTarget>();
  fg.active = target && target->valid();
  if (!fg.active) return;
  fg.graph.import_texture("color", target->texture, target->view,
                          {target->width, target->height, target->format, target->usage},
                          gpu::Access::Writable);
}

void execute_frame_graph(Registry& render) {
  auto& fg = render.resource<FrameGraph>();
  if (!fg.active) return;
  gpu::Context& ctx = *render.resource<GpuContext>();
  const gpu::CompiledGraph& plan = fg.graph.compile();
  if (fg.timing && !fg.timer_created) {
    // Room for passes that join later (overlays toggled on); extra ones go untimed.
    fg.timer = gpu::create_pass_timer(ctx, std::max(8u, plan.timed_passes));
    fg.timer_created = true;
  }
  if (!fg.dump_path.empty()) {
    std::ostringstream dot;
    fg.graph.dump_dot(dot);
    write_file_atomically(fg.dump_path, dot.str());
    fg.dump_path.clear();
  }
  // Pipelines made on first use wait for their validation, which may yield: before a late
  // target's texture is taken.
  fg.graph.prepare(ctx);
  if (auto& late = render.resource<RenderTarget>(); late.acquire) {
    // A late target's texture: nothing yields between here and the graph's submission.
    if (!late.acquire(late)) {
      fg.active = false;
      return;
    }
    fg.graph.bind_imported_texture("color", late.texture, late.view);
  }
  fg.graph.execute(ctx, fg.pool, fg.timing ? &fg.timer : nullptr);
  fg.executed = true;
  ctx.check("drawing a frame");

  auto& stats = render.resource<RenderStats>();
  const auto& target = render.resource<RenderTarget>();
  auto* requests = render.try_resource<ScreenshotRequests>();
  auto* capture = render.try_resource<FrameCapture>();
  bool want_capture = (requests && (!requests->paths.empty() || requests->capture)) ||
                      (capture && capture->on_frame);
  if (!want_capture) return;
  if (!(target.usage & WGPUTextureUsage_CopySrc)) {
    STIPPLE_WARN("this render target cannot be read back: no screenshot");
    if (requests) {
      requests->paths.clear();
      requests->capture = false;
    }
    return;
  }
  gpu::Image image =
      gpu::read_texture(ctx, target.texture, target.width, target.height, target.format);
  if (requests) {
    for (const auto& path : requests->paths) {
      gpu::write_png(path, image);
      STIPPLE_INFO("wrote {} ({}x{})", path, image.width, image.height);
    }
    requests->paths.clear();
    if (requests->capture) render.resource<CapturedFrame>().image = image;
    requests->capture = false;
  }
  if (capture && capture->on_frame) capture->on_frame(stats.frames, image);
}

// After every PostDraw system (presentation): waiting for the timestamps does not delay it.
void finish_render_frame(Registry& render) {
  auto& fg = render.resource<FrameGraph>();
  auto& stats = render.resource<RenderStats>();
  if (!fg.executed) return;
  gpu::Context& ctx = *render.resource<GpuContext>();
  std::map<std::string, double> times;
  if (fg.timing) times = fg.graph.read_pass_times(ctx, fg.timer);
  if (times.empty()) ctx.wait_idle();  // frames are waited for either way: times are per frame
  double total = 0;
  for (const auto& [name, ms] : times) total += ms;
  if (stats.keep_history) {
    for (uint32_t p : fg.graph.plan().order) stats.history[fg.graph.passes()[p].name];
    for (const auto& [name, ms] : times) stats.history[name].push_back(ms);
    if (!times.empty()) stats.gpu_ms.push_back(total);
    stats.wall_ms.push_back((now_seconds() - stats.frame_start) * 1e3);
  }
  stats.pass_ms = std::move(times);
  ++stats.frames;
}

void extract_screenshot_requests(Registry& main) {
  auto& requests = main.resource<ScreenshotRequests>();
  if (requests.paths.empty() && !requests.capture) return;
  auto& render = main.resource<RenderWorldRef>()->resource<ScreenshotRequests>();
  for (auto& p : requests.paths) render.paths.push_back(std::move(p));
  requests.paths.clear();
  render.capture = render.capture || requests.capture;
  requests.capture = false;
}

void extract_render_stats(Registry& main) {
  const auto& stats = main.resource<RenderWorldRef>()->resource<RenderStats>();
  auto& snapshot = main.resource<RenderStatsSnapshot>();
  snapshot.frames = stats.frames;
  snapshot.pass_ms = stats.pass_ms;
  snapshot.points_drawn = stats.points_drawn;
  snapshot.points_total = stats.points_total;
}

}  // namespace

void GpuPlugin::build(Engine& engine) {
  GpuContext gpu{std::shared_ptr<gpu::Context>(gpu::create_context(options))};
  engine.main().insert_resource(gpu);
  engine.render().insert_resource(gpu);
}

void RenderGraphPlugin::build(Engine& engine) {
  FrameGraph fg;
  fg.timing = timing;
  fg.dump_path = dump_graph;
  engine.render().insert_resource(std::move(fg));
  RenderStats stats;
  stats.keep_history = keep_history;
  engine.render().insert_resource(std::move(stats));
  engine.render().insert_resource(ScreenshotRequests{});
  engine.render().insert_resource(CapturedFrame{});
  engine.main().insert_resource(ScreenshotRequests{});
  engine.main().insert_resource(RenderStatsSnapshot{});
  engine.add_system(RenderStage::Prepare, start_render_frame, "start_render_frame");
  engine.add_system(MainStage::Extract, extract_screenshot_requests, "extract_screenshot_requests");
  engine.add_system(MainStage::Extract, extract_render_stats, "extract_render_stats");
}

void RenderGraphPlugin::finish(Engine& engine) {
  // Registered last, so they run after every plugin's systems of their stage.
  engine.add_system(RenderStage::Prepare, begin_frame_graph, "begin_frame_graph");
  engine.add_system(RenderStage::Draw, execute_frame_graph, "execute_frame_graph");
  engine.add_system(RenderStage::PostDraw, finish_render_frame, "finish_render_frame");
}

namespace {
struct HeadlessSchedule {
  uint64_t frames = 0;
  std::string output;
  bool capture = false;
  uint64_t frame = 0;
};
}  // namespace

void HeadlessTargetPlugin::build(Engine& engine) {
  if (width == 0 || height == 0) fail("HeadlessTargetPlugin: the target size must not be 0");
  engine.main().insert_resource(HeadlessSchedule{frames, output, capture, 0});
  engine.main().insert_resource(Viewport{width, height});
  HeadlessTarget target;
  target.width = width;
  target.height = height;
  engine.render().insert_resource(std::move(target));
  engine.add_system(
      MainStage::Update,
      [](Registry& main) {
        auto& s = main.resource<HeadlessSchedule>();
        uint64_t frame = s.frame++;
        if (s.frames == 0 || frame + 1 != s.frames) return;
        if (!s.output.empty()) main.resource<ScreenshotRequests>().paths.push_back(s.output);
        if (s.capture) main.resource<ScreenshotRequests>().capture = true;
        main.resource<AppExit>().requested = true;
      },
      "headless_schedule");
  engine.add_system(
      RenderStage::Prepare,
      [](Registry& render) {
        auto& t = render.resource<HeadlessTarget>();
        if (!t.color) {
          // Storage: compute passes may write the image (the compute rasterizer's display).
          const WGPUTextureUsage usage = WGPUTextureUsage_RenderAttachment |
                                         WGPUTextureUsage_CopySrc | WGPUTextureUsage_StorageBinding;
          t.color = gpu::create_texture_2d(*render.resource<GpuContext>(), t.width, t.height,
                                           WGPUTextureFormat_RGBA8Unorm, usage, "headless-color");
          t.view = gpu::create_view(t.color);
        }
        RenderTarget target;
        target.texture = t.color.get();
        target.view = t.view.get();
        target.width = t.width;
        target.height = t.height;
        target.format = WGPUTextureFormat_RGBA8Unorm;
        target.usage = WGPUTextureUsage_RenderAttachment | WGPUTextureUsage_CopySrc |
                       WGPUTextureUsage_StorageBinding;
        render.insert_resource(target);
      },
      "headless_target");
}

}  // namespace stipple
