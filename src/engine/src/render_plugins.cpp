#include "stipple/engine/render_plugins.hpp"

#include <algorithm>
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
  auto& fg = render.resource<FrameGraph>();
  fg.executed = false;
  fg.timed = false;
}

// After every Prepare system of every plugin: the target is known.
void begin_frame_graph(Registry& render) {
  auto& fg = render.resource<FrameGraph>();
  fg.graph = gpu::RenderGraph{};
  fg.redraw_checks.clear();
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
  if (fg.timing && !fg.timers_created) {
    // Room for passes that join later (overlays toggled on); extra ones go untimed.
    fg.timers = gpu::create_pass_timer_ring(ctx, std::max(8u, plan.timed_passes), fg.timer_slots);
    fg.timers_created = true;
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
  auto& stats = render.resource<RenderStats>();
  gpu::PassTimer* timer = gpu::acquire_pass_timer(fg.timers);
  if (!timer && !fg.timers.slots.empty()) ++stats.untimed_frames;
  fg.graph.execute(ctx, fg.pool, timer);
  fg.executed = true;
  ctx.check("drawing a frame");
  // Mapped now, so that the results come back while the GPU and the next frames go on.
  if (timer) {
    std::vector<std::string> names = fg.graph.timed_pass_names(*timer);
    fg.timed = std::any_of(names.begin(), names.end(), [](const auto& n) { return !n.empty(); });
    gpu::pass_timer_submitted(fg.timers, timer, stats.frames + 1, std::move(names));
  }

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
  // A kept frame is whole: drawn again while a check finds it was not (redraw_checks). Checked
  // once it is read (the checks may wait, which yields the page's thread, and a browser canvas's
  // texture expires then: it is taken again for the next draw), and drawn untimed (the frame's
  // timer is already on its way back).
  for (int again = 0; again < 2; ++again) {
    bool redraw = false;
    for (auto& check : fg.redraw_checks) redraw = check(ctx) || redraw;
    if (!redraw) break;
    if (auto& late = render.resource<RenderTarget>(); late.acquire) {
      if (!late.acquire(late)) break;
      fg.graph.bind_imported_texture("color", late.texture, late.view);
    }
    fg.graph.execute(ctx, fg.pool, nullptr);
    ctx.check("drawing a frame again");
    image = gpu::read_texture(ctx, target.texture, target.width, target.height, target.format);
  }
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

// Appends to a history, which keeps its last `limit` entries (0: all).
template <typename T>
void keep(std::vector<T>& history, T value, uint32_t limit) {
  if (limit > 0 && history.size() >= limit)
    history.erase(history.begin(), history.begin() + ptrdiff_t(history.size() - limit + 1));
  history.push_back(value);
}

// Arrived frames' times into the stats, in frame order.
void take_pass_times(RenderStats& stats, std::vector<gpu::FrameTimes> arrived) {
  for (gpu::FrameTimes& frame : arrived) {
    if (stats.keep_history) {
      double total = 0;
      for (const auto& [name, ms] : frame.pass_ms) {
        keep(stats.history[name], ms, stats.history_limit);
        total += ms;
      }
      keep(stats.gpu_ms, total, stats.history_limit);
      keep(stats.gpu_frames, frame.frame, stats.history_limit);
    }
    stats.pass_ms = std::move(frame.pass_ms);
    stats.pass_ms_frame = frame.frame;
  }
}

// After every PostDraw system (presentation): waiting for the timestamps does not delay it.
void finish_render_frame(Registry& render) {
  auto& fg = render.resource<FrameGraph>();
  auto& stats = render.resource<RenderStats>();
  gpu::Context& ctx = *render.resource<GpuContext>();
  // Earlier frames' results are taken even when this one drew nothing.
  take_pass_times(stats, gpu::collect_pass_times(ctx, fg.timers, fg.wait_for_gpu));
  if (!fg.executed) return;
  // A frame waited for has its times by now; one without any is waited for all the same, so
  // that wall times mean the same either way.
  if (fg.wait_for_gpu && !fg.timed) ctx.wait_idle();
  if (!fg.wait_for_gpu && fg.max_frames_in_flight > 0) {
    const uint64_t serial = fg.fence.mark(ctx);
    ctx.wait_until(
        [&] { return fg.fence.completed() + fg.max_frames_in_flight > serial || ctx.lost; });
  }
  if (stats.keep_history) {
    for (uint32_t p : fg.graph.plan().order) stats.history[fg.graph.passes()[p].name];
    keep(stats.wall_ms, (now_seconds() - stats.frame_start) * 1e3, stats.history_limit);
  }
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
  snapshot.pass_ms_frame = stats.pass_ms_frame;
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
  fg.wait_for_gpu = wait_for_gpu;
  // Frames waited for have one timer in use at a time.
  fg.timer_slots = wait_for_gpu ? 1 : std::max(1u, timer_slots);
  fg.max_frames_in_flight = max_frames_in_flight;
  fg.dump_path = dump_graph;
  engine.render().insert_resource(std::move(fg));
  RenderStats stats;
  stats.keep_history = keep_history;
  stats.history_limit = history_limit;
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

void drain_pass_times(Engine& engine, bool wait) {
  engine.wait_for_render();
  Registry& render = engine.render();
  auto* fg = render.try_resource<FrameGraph>();
  if (!fg || fg->timers.slots.empty()) return;
  take_pass_times(render.resource<RenderStats>(),
                  gpu::collect_pass_times(*render.resource<GpuContext>(), fg->timers, wait));
}

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
