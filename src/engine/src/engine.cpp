#include "stipple/engine/engine.hpp"

#include <algorithm>
#include <chrono>
#include <utility>

#include <fmt/format.h>

#include "stipple/core/log.hpp"

namespace stipple {
namespace {

double ms_between(std::chrono::steady_clock::time_point a,
                  std::chrono::steady_clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

}  // namespace

Engine::Engine() {
  install_render_sync(main_.registry);
  main_.registry.insert_resource(AppExit{});
}

Engine::~Engine() {
  try {
    shutdown();
  } catch (const std::exception& e) {
    STIPPLE_ERROR("render thread failed during shutdown: {}", e.what());
  } catch (...) {
    STIPPLE_ERROR("render thread failed during shutdown");
  }
}

void Engine::add_system(MainStage stage, System system, std::string name) {
  main_.stages[size_t(stage)].push_back({std::move(name), std::move(system)});
}

void Engine::add_system(RenderStage stage, System system, std::string name) {
  render_.stages[size_t(stage)].push_back({std::move(name), std::move(system)});
}

const Engine::PluginEntry* Engine::find_plugin(uint32_t type) const {
  for (const auto& p : plugins_)
    if (p.type == type) return &p;
  return nullptr;
}

bool Engine::has_plugin(std::string_view name) const {
  return std::any_of(plugins_.begin(), plugins_.end(),
                     [&](const PluginEntry& p) { return p.info.name == name; });
}

void Engine::check_new_plugin(uint32_t type, std::string_view name) const {
  if (built_) fail("plugin {} added after the engine was built", name);
  if (find_plugin(type)) fail("plugin {} was added twice", name);
  if (has_plugin(name))
    fail("plugin {} was added twice (another plugin type already has this name)", name);
}

void Engine::missing_plugin(std::string_view requirer, std::string_view required) {
  fail("plugin {} requires plugin {}, which was not added", requirer, required);
}

std::vector<PluginInfo> Engine::plugins() const {
  std::vector<PluginInfo> infos;
  for (const auto& p : plugins_) infos.push_back(p.info);
  return infos;
}

void Engine::set_pipelined(bool pipelined) {
  if (built_) fail("the rendering mode cannot change after the engine was built");
  pipelined_ = pipelined;
}

void Engine::build() {
  if (built_) return;
  // By index: require()/finish() may not add plugins (add_plugin throws once built_), but an
  // entry reference must not outlive a push_back anyway.
  for (size_t i = 0; i < plugins_.size(); ++i) {
    for (const auto& dep : plugins_[i].info.dependencies)
      if (!has_plugin(dep)) missing_plugin(plugins_[i].info.name, dep);
    if (plugins_[i].require) plugins_[i].require(*this);
  }
  for (size_t i = 0; i < plugins_.size(); ++i)
    if (plugins_[i].finish) plugins_[i].finish(*this);
  built_ = true;
  if (pipelined_) render_thread_ = std::thread([this] { render_thread_main(); });
}

void Engine::update() {
  if (stopped_) fail("the engine was shut down");
  build();
  const auto start = std::chrono::steady_clock::now();
  for (MainStage stage :
       {MainStage::Input, MainStage::PreUpdate, MainStage::Update, MainStage::PostUpdate})
    main_.run_stage(size_t(stage));
  extract();
  // Sequential: the render stages ran inside extract() and are counted there, not here.
  main_cpu_ms_ += ms_between(start, std::chrono::steady_clock::now()) - last_inline_render_ms_;
  last_inline_render_ms_ = 0;
  ++frames_;
}

void Engine::run(uint64_t max_frames) {
  build();
  auto& exit = main_.registry.resource<AppExit>();
  exit.requested = false;
  while (!main_.registry.resource<AppExit>().requested && (max_frames == 0 || frames_ < max_frames))
    update();
  wait_for_render();
}

void Engine::extract() {
  if (pipelined_) {
    render_idle_.acquire();  // the render thread has finished frame N-1
    if (render_error_) {
      std::exception_ptr error = std::exchange(render_error_, nullptr);
      render_idle_.release();
      std::rethrow_exception(error);
    }
  }
  Registry& main = main_.registry;
  try {
    apply_render_sync(main, render_.registry);
    main.insert_resource(RenderWorldRef{&render_.registry});
    main_.run_stage(size_t(MainStage::Extract));
    main.remove_resource<RenderWorldRef>();
  } catch (...) {
    main.remove_resource<RenderWorldRef>();
    if (pipelined_) render_idle_.release();  // nothing was started: the render world stays idle
    throw;
  }
  if (pipelined_)
    render_start_.release();  // the render thread draws frame N; we go on to frame N+1
  else
    run_render_stages();
}

void Engine::run_render_stages() {
  auto t = std::chrono::steady_clock::now();
  const auto start = t;
  for (RenderStage stage : {RenderStage::Prepare, RenderStage::Queue, RenderStage::PreDraw,
                            RenderStage::Draw, RenderStage::PostDraw}) {
    render_.run_stage(size_t(stage));
    const auto now = std::chrono::steady_clock::now();
    render_cpu_ms_[size_t(stage)] += ms_between(t, now);
    t = now;
  }
  if (!pipelined_) last_inline_render_ms_ = ms_between(start, t);
}

void Engine::render_thread_main() {
  for (;;) {
    render_start_.acquire();
    if (stop_render_thread_) return;
    try {
      run_render_stages();
    } catch (...) {
      render_error_ = std::current_exception();  // handed to the main thread at the next sync
    }
    render_idle_.release();
  }
}

void Engine::wait_for_render() {
  if (!render_thread_.joinable()) return;
  render_idle_.acquire();
  std::exception_ptr error = std::exchange(render_error_, nullptr);
  render_idle_.release();
  if (error) std::rethrow_exception(error);
}

void Engine::shutdown() {
  stopped_ = true;
  if (!render_thread_.joinable()) return;
  render_idle_.acquire();  // the frame in flight, if any, finishes first
  stop_render_thread_ = true;
  render_start_.release();
  render_thread_.join();
  render_idle_.release();
  if (std::exception_ptr error = std::exchange(render_error_, nullptr))
    std::rethrow_exception(error);
}

std::string plugins_dot(const std::vector<PluginInfo>& plugins) {
  std::string dot =
      "digraph plugins {\n  rankdir=BT;\n  node [shape=box, fontname=\"Helvetica\"];\n";
  for (const auto& p : plugins) dot += fmt::format("  \"{}\";\n", p.name);
  for (const auto& p : plugins) {
    for (const auto& d : p.dependencies) dot += fmt::format("  \"{}\" -> \"{}\";\n", p.name, d);
    for (const auto& d : p.optional_dependencies)
      dot += fmt::format("  \"{}\" -> \"{}\" [style=dashed];\n", p.name, d);
  }
  dot += "}\n";
  return dot;
}

}  // namespace stipple
