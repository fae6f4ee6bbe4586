// The browser build has no pointlet cache (scene_virtual.cpp is native): a virtualized scene
// is refused with the reason, and there is never one to frame.
#include "stipple/core/error.hpp"
#include "virtual_scene.hpp"

namespace stipple::scene {

void add_virtual_scene(Engine&, const ScenePlan& plan) {
  fail("{}: the browser build has no pointlet cache for the virtualized path ({})",
       plan.options.inputs.empty() ? std::string("the scene") : plan.options.inputs[0],
       plan.source.virtual_reason);
}

void fit_virtual_scene(ViewFit&, Registry&) {}

}  // namespace stipple::scene
