#pragma once
// The renderer's built-in plugins: GpuPlugin (the WebGPU device), RenderGraphPlugin (the frame's
// render graph, built in Prepare..PreDraw and executed in Draw) and HeadlessTargetPlugin (an
// offscreen colour target and PNG output). A window's surface target lives in the app
// (SurfaceTargetPlugin): any plugin that fills RenderTarget in Prepare can replace the headless
// one.
//
// Render-world frame, in stage order:
//   Prepare   targets set RenderTarget (acquire a surface texture, or an offscreen texture);
//             uploads; then (registered in finish(), so after every plugin's Prepare systems)
//             RenderGraphPlugin starts a new graph with the target imported as "color"
//   Queue     scene passes (points)
//   PreDraw   overlay passes (UI)
//   Draw      RenderGraphPlugin compiles and executes the graph, then serves capture requests
//   PostDraw  targets present; then (finish()) the pass times that arrived are taken into
//             RenderStats: this frame's, waiting for the GPU to finish it (the default), or,
//             with RenderGraphPlugin::wait_for_gpu off, those of earlier frames whose results
//             have come back (none is waited for; drain_pass_times waits for the rest)
#include <array>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "stipple/engine/registry.hpp"
#include "stipple/renderer/frame_fence.hpp"
#include "stipple/renderer/gpu.hpp"
#include "stipple/renderer/gpu_timer.hpp"
#include "stipple/renderer/render_graph.hpp"

namespace stipple {

class Engine;

// Render-world resource (and main-world, for plugins that create GPU objects before the first
// frame, e.g. a window surface): the device, shared by both worlds.
struct GpuContext {
  std::shared_ptr<gpu::Context> context;
  gpu::Context& operator*() const { return *context; }
  gpu::Context* operator->() const { return context.get(); }
};

struct GpuPlugin {
  static constexpr std::string_view name = "GpuPlugin";
  static constexpr std::string_view description =
      "WebGPU device (wgpu-native or Dawn) as GpuContext in both worlds";
  gpu::ContextOptions options;
  void build(Engine& engine);
};

// Render-world resource: where this frame is drawn. Set by a target plugin in Prepare; invalid
// (no texture) when there is nothing to draw into (a minimised window), and then no graph runs.
// A target whose texture must be taken just before the frame is submitted (a browser canvas's
// expires whenever the page's thread yields, which Prepare and Queue systems may do: shader
// compilation, buffer mapping) leaves texture and view null and sets `acquire`, which the graph's
// Draw system calls right before it runs the graph: it fills texture and view, or returns false
// to skip the frame.
struct RenderTarget {
  WGPUTexture texture = nullptr;  // not owned
  WGPUTextureView view = nullptr;
  uint32_t width = 0, height = 0;
  WGPUTextureFormat format = WGPUTextureFormat_RGBA8Unorm;
  WGPUTextureUsage usage = WGPUTextureUsage_RenderAttachment;
  std::function<bool(RenderTarget&)> acquire;
  bool valid() const { return (acquire || (texture && view)) && width > 0 && height > 0; }
};

// Render-world resource: this frame's graph and what lives across frames.
struct FrameGraph {
  gpu::RenderGraph graph;
  bool active = false;  // a target was available: passes may be added and the graph runs
  gpu::TransientPool pool;
  gpu::PassTimerRing timers;  // one slot per frame in flight
  bool timers_created = false;
  bool timing = true;
  bool wait_for_gpu = true;  // RenderGraphPlugin's
  uint32_t timer_slots = 1;
  uint32_t max_frames_in_flight = 0;  // RenderGraphPlugin's
  gpu::FrameFence fence;              // frames submitted and finished, when that is bounded
  std::string dump_path;              // write the first frame's graph as DOT
  bool executed = false;              // this frame
  bool timed = false;                 // this frame's passes are being timed
  // This frame's checks that it is whole, added by Queue systems (cleared each frame). They run
  // only in a frame that is captured (a screenshot, CapturedFrame, FrameCapture), once it is
  // read back, and may wait for the GPU: one that returns true found the frame incomplete (a
  // buffer too small for what it drew, grown since) and the graph runs again, untimed, and is
  // read again (at most twice). Frames not captured never wait for them.
  std::vector<std::function<bool(gpu::Context&)>> redraw_checks;
};

// Render-world resource: statistics of the frames drawn so far.
// A frame's number is the value `frames` has once that frame is counted (the first drawn is 1).
struct RenderStats {
  uint64_t frames = 0;  // frames whose graph ran
  // GPU milliseconds per pass of the newest frame whose times arrived (this frame's, when frames
  // wait for the GPU), and that frame's number (0: none yet).
  std::map<std::string, double> pass_ms;
  uint64_t pass_ms_frame = 0;
  // With keep_history, in frame order: per pass, its time in every timed frame that ran it;
  // per timed frame its total GPU time (gpu_ms) and number (gpu_frames); per drawn frame the
  // time from Prepare to the end of PostDraw (wall_ms: with the GPU's share where frames wait
  // for it, the CPU's alone where they do not).
  std::map<std::string, std::vector<double>> history;
  std::vector<double> gpu_ms;
  std::vector<uint64_t> gpu_frames;
  std::vector<double> wall_ms;
  bool keep_history = false;
  uint32_t history_limit = 0;  // each of them keeps its last this many entries (0: all)
  // Frames drawn without times: every timer slot's results were still on their way.
  uint64_t untimed_frames = 0;
  uint64_t points_drawn = 0;  // last frame (set by the point passes)
  uint64_t points_total = 0;
  double frame_start = 0;  // internal: when Prepare began
};

// Main-world resource: the render world's statistics as of the last Extract (for UIs; in
// pipelined mode they describe the frame before the one just extracted).
struct RenderStatsSnapshot {
  uint64_t frames = 0;
  std::map<std::string, double> pass_ms;
  uint64_t pass_ms_frame = 0;
  uint64_t points_drawn = 0, points_total = 0;
};

// Main-world resource: PNG files to write from the next drawn frame (the target as presented,
// overlays included), and whether to keep that frame in memory (CapturedFrame). Moved to the
// render world in Extract.
struct ScreenshotRequests {
  std::vector<std::string> paths;
  bool capture = false;
};
// Render-world resource: the frame a ScreenshotRequests::capture asked for (RGBA8, top row
// first); empty until then.
struct CapturedFrame {
  gpu::Image image;
};
// Render-world resource: every drawn frame handed to a callback (tests compare frames).
struct FrameCapture {
  std::function<void(uint64_t frame, const gpu::Image&)> on_frame;
};

struct RenderGraphPlugin {
  static constexpr std::string_view name = "RenderGraphPlugin";
  static constexpr std::string_view description =
      "per-frame render graph with the target imported as \"color\"; pass timing, screenshots";
  static constexpr std::array<std::string_view, 1> dependencies{"GpuPlugin"};
  bool timing = true;
  bool keep_history = false;   // every frame's pass times in RenderStats::history
  uint32_t history_limit = 0;  // RenderStats's: the last this many frames' (0: all)
  std::string dump_graph;      // DOT of the first frame's graph
  // Whether a frame ends by waiting for the GPU to finish it, so that RenderStats holds its own
  // pass times and wall_ms includes the GPU's work (what `stipple render --stats` and the bench
  // commands report). Off (the web page): a frame ends once submitted; its times are read back
  // through a ring of `timer_slots` timers and arrive a few frames later (a frame that finds
  // every slot in flight goes untimed); drain_pass_times waits for those still on their way.
  bool wait_for_gpu = true;
  uint32_t timer_slots = 4;
  // Without wait_for_gpu: a frame ends by waiting until at most this many frames (its own
  // included) are unfinished on the GPU, so the CPU runs ahead of the GPU by a bounded amount,
  // as a swapchain's present does (a headless benchmark has none). 0: unbounded (the web page,
  // which must not block).
  uint32_t max_frames_in_flight = 0;
  void build(Engine& engine);
  void finish(Engine& engine);
};

// Takes the pass times that have arrived into RenderStats, in frame order, after waiting for the
// render world (a pipelined frame in flight); with `wait`, every timed frame still on its way is
// waited for first (after N frames and a drain, RenderStats has the times of every timed frame).
// Without, nothing blocks: a page that stopped drawing still gets its last frames' times.
void drain_pass_times(Engine& engine, bool wait = true);

// An offscreen RGBA8 target. With `output` set, the last of `frames` is written there as PNG;
// with `capture`, it is kept in the render world's CapturedFrame; with `frames` > 0 the app
// exits after that many.
struct HeadlessTargetPlugin {
  static constexpr std::string_view name = "HeadlessTargetPlugin";
  static constexpr std::string_view description =
      "offscreen colour target; PNG of a chosen frame; exit after N frames";
  static constexpr std::array<std::string_view, 2> dependencies{"GpuPlugin", "RenderGraphPlugin"};
  uint32_t width = 1280, height = 720;
  std::string output;
  uint64_t frames = 1;  // 0: run until something else asks to exit
  bool capture = false;
  void build(Engine& engine);
};

// Render-world resource of HeadlessTargetPlugin: the texture it owns.
struct HeadlessTarget {
  gpu::Texture color;
  gpu::TextureView view;
  uint32_t width = 0, height = 0;
};

}  // namespace stipple
