#pragma once
// The scene of `stipple render` and `stipple view` (stipple/scene/scene.hpp, in libstipple) and
// the flags that set it.
#include <CLI/CLI.hpp>

#include "stipple/app/filter_options.hpp"
#include "stipple/scene/scene.hpp"

namespace stipple::app {

using scene::add_engine_core;
using scene::add_scene_plugin;
using scene::EngineCore;
using scene::frame_scene;
using scene::place_camera;
using scene::plan_scene;
using scene::Renderer;
using scene::renderer_name;
using scene::SceneOptions;
using scene::ScenePlan;
using scene::SceneView;

// --renderer, --hqs, --max-sse, --memory-mb and the virtualized path's --virtual, --bucket,
// --pointlets, --cache, --host-memory, --gpu-memory, and the filter and clip flags: the same
// for `render` and `view`.
void add_scene_options(CLI::App* cmd, SceneOptions& options);

}  // namespace stipple::app
