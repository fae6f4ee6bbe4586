#include "stipple/engine/world.hpp"

namespace stipple {

const char* stage_name(MainStage stage) {
  switch (stage) {
    case MainStage::Input:
      return "Input";
    case MainStage::PreUpdate:
      return "PreUpdate";
    case MainStage::Update:
      return "Update";
    case MainStage::PostUpdate:
      return "PostUpdate";
    case MainStage::Extract:
      return "Extract";
  }
  return "?";
}

const char* stage_name(RenderStage stage) {
  switch (stage) {
    case RenderStage::Prepare:
      return "Prepare";
    case RenderStage::Queue:
      return "Queue";
    case RenderStage::PreDraw:
      return "PreDraw";
    case RenderStage::Draw:
      return "Draw";
    case RenderStage::PostDraw:
      return "PostDraw";
  }
  return "?";
}

void World::run_stage(size_t stage) {
  // By index over a deque: a system may add systems (they run this frame if in this stage).
  auto& systems = stages[stage];
  for (size_t i = 0; i < systems.size(); ++i) systems[i].run(registry);
}

}  // namespace stipple
