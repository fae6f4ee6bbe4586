#pragma once
// Worlds and stages (seed 000, section 3.3, Table 1). The main world is the source of truth;
// the render world holds what rendering needs, copied over in Extract, the only point where the
// two meet. Systems are free functions (or lambdas) over one registry, run by stage and, within
// a stage, in registration order.
#include <array>
#include <deque>
#include <functional>
#include <string>
#include <vector>

#include "stipple/engine/registry.hpp"

namespace stipple {

enum class MainStage { Input, PreUpdate, Update, PostUpdate, Extract };
enum class RenderStage { Prepare, Queue, PreDraw, Draw, PostDraw };
inline constexpr std::array kMainStages = {MainStage::Input, MainStage::PreUpdate,
                                           MainStage::Update, MainStage::PostUpdate,
                                           MainStage::Extract};
inline constexpr std::array kRenderStages = {RenderStage::Prepare, RenderStage::Queue,
                                             RenderStage::PreDraw, RenderStage::Draw,
                                             RenderStage::PostDraw};
const char* stage_name(MainStage stage);
const char* stage_name(RenderStage stage);

using System = std::function<void(Registry&)>;

struct SystemEntry {
  std::string name;  // for logs and errors; may be empty
  System run;
};

struct World {
  Registry registry;
  std::array<std::deque<SystemEntry>, 5> stages;  // indexed by MainStage or RenderStage

  // Runs the stage's systems in order; an exception stops the stage and propagates.
  void run_stage(size_t stage);
};

// Tags naming the worlds, for SyncTo<...>.
struct RenderWorldTag {};

// Inserted into the main registry only while Extract runs (the render thread is idle then), so
// extraction systems can write the render registry: the paper's "render registry injected as a
// shared resource".
struct RenderWorldRef {
  Registry* registry = nullptr;
  Registry& operator*() const { return *registry; }
  Registry* operator->() const { return registry; }
};

// Asks Engine::run() to stop after the current frame.
struct AppExit {
  bool requested = false;
};

}  // namespace stipple
