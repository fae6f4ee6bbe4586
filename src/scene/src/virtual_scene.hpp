#pragma once
// The virtualized path of the scene (seed 002's pointlet cache, pc::VirtualPointCloudPlugin):
// scene_virtual.cpp natively; scene_virtual_web.cpp in the browser build, which has no pointlet
// cache (its zlib-compressed pages are not built there).
#include "stipple/math/camera.hpp"
#include "stipple/scene/scene.hpp"

namespace stipple::scene {

// Adds the virtualized point cloud for plan.options.inputs (plan.source.virtualized) within the
// host budget, and says on stdout whether the cache was built or reused.
void add_virtual_scene(Engine& engine, const ScenePlan& plan);

// Builds the pointlet cache add_virtual_scene would open for these options and this host
// budget (or finds it current), quietly: render --progressive runs it on another thread while
// its first image is drawn. Native only.
void build_virtual_cache(const SceneOptions& options, uint64_t host_budget);

// Fits `fit` to a virtualized cloud's points, where the scene has one.
void fit_virtual_scene(ViewFit& fit, Registry& main);

}  // namespace stipple::scene
