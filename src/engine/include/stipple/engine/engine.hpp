#pragma once
// The engine (seed 000, sections 3.1-3.3): plugins compose two worlds of systems, and a frame
// runs main Input..PostUpdate, then the Extract sync point, then render Prepare..PostDraw, either
// on the same thread or, pipelined, on a render thread that draws frame N while the main thread
// simulates frame N+1.
//
// A plugin is any type with `void build(Engine&)`. Optional members:
//   void require(Engine&)   checks run by Engine::build() once every plugin is added
//   void finish(Engine&)    runs after every plugin's build() and require(), in order added
//   static constexpr std::string_view name, description;
//   static constexpr std::array<std::string_view, N> dependencies, optional_dependencies;
// Declared dependencies are checked by name at build(), so a replacement plugin that declares
// the same name satisfies the plugins that depend on the original.
#include <array>
#include <concepts>
#include <exception>
#include <memory>
#include <semaphore>
#include <string>
#include <string_view>
#include <thread>
#include <tuple>
#include <vector>

#include "stipple/core/error.hpp"
#include "stipple/engine/registry.hpp"
#include "stipple/engine/sync.hpp"
#include "stipple/engine/world.hpp"

namespace stipple {

class Engine;

template <typename P>
concept Plugin = requires(P plugin, Engine& engine) {
  { plugin.build(engine) } -> std::same_as<void>;
};

// What `stipple plugins` prints about a plugin.
struct PluginInfo {
  std::string name;
  std::string description;
  std::vector<std::string> dependencies;           // required
  std::vector<std::string> optional_dependencies;  // used when present
};

template <Plugin P>
std::string_view plugin_name() {
  if constexpr (requires { std::string_view(P::name); })
    return P::name;
  else
    return type_name<P>();
}

template <Plugin P>
PluginInfo plugin_info() {
  PluginInfo info;
  info.name = plugin_name<P>();
  if constexpr (requires { std::string_view(P::description); }) info.description = P::description;
  if constexpr (requires { P::dependencies; })
    for (std::string_view d : P::dependencies) info.dependencies.emplace_back(d);
  if constexpr (requires { P::optional_dependencies; })
    for (std::string_view d : P::optional_dependencies) info.optional_dependencies.emplace_back(d);
  return info;
}

// Several plugins added as one: engine.add_plugins(PluginGroup{A{}, B{}}).
template <Plugin... Ps>
struct PluginGroup {
  std::tuple<Ps...> plugins;
  explicit PluginGroup(Ps... ps) : plugins(std::move(ps)...) {}
};

class Engine {
 public:
  Engine();
  ~Engine();  // stops the render thread; never throws (a late render error is logged)
  Engine(const Engine&) = delete;
  Engine& operator=(const Engine&) = delete;

  World& main_world() { return main_; }
  World& render_world() { return render_; }
  Registry& main() { return main_.registry; }
  Registry& render() { return render_.registry; }

  void add_system(MainStage stage, System system, std::string name = {});
  void add_system(RenderStage stage, System system, std::string name = {});

  // Builds the plugin now. Adding a plugin type twice, or two plugins of one name, throws.
  template <Plugin P>
  Engine& add_plugin(P plugin);
  template <Plugin... Ps>
  Engine& add_plugins(Ps... plugins) {
    (add_plugin(std::move(plugins)), ...);
    return *this;
  }
  template <Plugin... Ps>
  Engine& add_plugins(PluginGroup<Ps...> group) {
    std::apply([&](auto&... ps) { (add_plugin(std::move(ps)), ...); }, group.plugins);
    return *this;
  }
  template <Plugin P>
  bool has_plugin() const {
    return find_plugin(type_id<P>()) != nullptr;
  }
  bool has_plugin(std::string_view name) const;
  // The added instance (to read its settings), or null.
  template <Plugin P>
  P* get_plugin() {
    const PluginEntry* entry = find_plugin(type_id<P>());
    return entry ? static_cast<P*>(entry->instance.get()) : nullptr;
  }
  // For require(): throws naming both plugins when `Required` is absent.
  template <Plugin Required>
  void require_plugin(std::string_view requirer) const {
    if (!has_plugin<Required>()) missing_plugin(requirer, plugin_name<Required>());
  }
  // Plugins in the order added.
  std::vector<PluginInfo> plugins() const;

  // Pipelined: the render world runs on its own thread. Set before build().
  void set_pipelined(bool pipelined);
  bool pipelined() const { return pipelined_; }

  // Checks declared dependencies and runs require() of every plugin, then finish() in order, then
  // starts the render thread when pipelined. update() and run() call it when needed.
  void build();
  bool built() const { return built_; }

  // One main frame and the sync point; the render stages of this frame run inline, or on the
  // render thread while the caller goes on. An exception thrown by a render system of an earlier
  // frame is rethrown here, on the main thread.
  void update();
  // update() until a system sets AppExit::requested (or max_frames, when non-zero), then waits
  // for the last render frame.
  void run(uint64_t max_frames = 0);
  // Waits until the render world is idle (the frame in flight is drawn), rethrowing its error.
  void wait_for_render();
  // Waits for the frame in flight and stops the render thread; rethrows a pending render error.
  // The engine can no longer update afterwards.
  void shutdown();
  uint64_t frames() const { return frames_; }  // completed update() calls
  // CPU milliseconds summed over every frame so far: of the main stages (Input..Extract, the
  // wait for the render world at the sync point included) and of each render stage (indexed by
  // RenderStage; read them while the render world is idle: after wait_for_render()).
  double main_cpu_ms() const { return main_cpu_ms_; }
  const std::array<double, 5>& render_cpu_ms() const { return render_cpu_ms_; }

 private:
  struct PluginEntry {
    uint32_t type = 0;
    PluginInfo info;
    std::shared_ptr<void> instance;
    std::function<void(Engine&)> require, finish;
  };
  const PluginEntry* find_plugin(uint32_t type) const;
  void check_new_plugin(uint32_t type, std::string_view name) const;
  [[noreturn]] static void missing_plugin(std::string_view requirer, std::string_view required);
  void extract();
  void run_render_stages();
  void render_thread_main();

  World main_;
  World render_;
  std::vector<PluginEntry> plugins_;
  bool pipelined_ = false;
  bool built_ = false;
  bool stopped_ = false;
  uint64_t frames_ = 0;
  double main_cpu_ms_ = 0;
  std::array<double, 5> render_cpu_ms_{};
  double last_inline_render_ms_ = 0;  // sequential: the render stages inside this update()

  // Pipelining: the main thread acquires render_idle_ at the sync point (the render thread
  // released it when it finished the previous frame), extracts, then releases render_start_.
  // Both semaphores also order the plain fields below between the two threads.
  std::binary_semaphore render_start_{0};
  std::binary_semaphore render_idle_{1};
  std::thread render_thread_;
  bool stop_render_thread_ = false;
  std::exception_ptr render_error_;
};

template <Plugin P>
Engine& Engine::add_plugin(P plugin) {
  std::string_view name = plugin_name<P>();
  check_new_plugin(type_id<P>(), name);
  auto instance = std::make_shared<P>(std::move(plugin));
  PluginEntry entry;
  entry.type = type_id<P>();
  entry.info = plugin_info<P>();
  entry.instance = instance;
  if constexpr (requires(P p, Engine & e) { p.require(e); })
    entry.require = [instance](Engine& e) { instance->require(e); };
  if constexpr (requires(P p, Engine & e) { p.finish(e); })
    entry.finish = [instance](Engine& e) { instance->finish(e); };
  // Recorded before build(), so has_plugin<P>() holds inside it and plugins it adds come after.
  plugins_.push_back(std::move(entry));
  instance->build(*this);
  return *this;
}

// Graphviz DOT of plugins and their dependencies (solid: required, dashed: optional), like the
// paper's Figure 3.
std::string plugins_dot(const std::vector<PluginInfo>& plugins);

}  // namespace stipple
