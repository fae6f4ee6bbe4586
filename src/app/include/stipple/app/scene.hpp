#pragma once
// The scene of `stipple render` and `stipple view` (stipple/scene/scene.hpp, in libstipple) and
// the flags that set it.
#include <CLI/CLI.hpp>

#include "stipple/app/filter_options.hpp"
#include "stipple/scene/scene.hpp"

namespace stipple::app {

using scene::add_scene_plugin;
using scene::apply_filters;
using scene::frame_scene;
using scene::is_tileset_scene;
using scene::max_sse_for;
using scene::Renderer;
using scene::renderer_name;
using scene::resolve_renderer;
using scene::scene_camera;
using scene::SceneOptions;
using scene::use_virtual_path;

// --renderer, --hqs, --max-sse, --memory-mb and the virtualized path's --virtual, --bucket,
// --pointlets, --cache, --host-memory, --gpu-memory, and the filter and clip flags: the same
// for `render` and `view`.
void add_scene_options(CLI::App* cmd, SceneOptions& options);

}  // namespace stipple::app
