#pragma once
// Plugins over the platform module: WindowPlugin (a GLFW window, polled in Input), InputPlugin
// (InputState from the window's events) and SurfaceTargetPlugin (the window's WebGPU surface as
// the frame's RenderTarget, reconfigured on resize and vsync changes; nothing is drawn while
// the window is minimised). GLFW runs on the main thread only: the render world sees sizes and
// settings through Extract.
#include <array>
#include <memory>
#include <string_view>
#include <vector>

#include <glm/vec2.hpp>

#include "stipple/platform/input.hpp"
#include "stipple/platform/window.hpp"

namespace stipple {
class Engine;
}

namespace stipple::viewer {

// Main-world resource.
struct WindowState {
  std::shared_ptr<platform::Window> window;  // shared: the UI backend keeps it until it is done
  std::vector<platform::InputEvent> events;  // this frame's
  glm::uvec2 framebuffer_size{0};            // pixels
  glm::uvec2 window_size{0};                 // screen coordinates (cursor positions)
  bool minimised = false;
};

struct WindowPlugin {
  static constexpr std::string_view name = "WindowPlugin";
  static constexpr std::string_view description =
      "GLFW window (no client API), events polled in Input; closing it exits";
  platform::WindowOptions options;
  void build(Engine& engine);
};

// Main-world resource InputState (platform/input.hpp), rebuilt in Input from WindowState.
struct InputPlugin {
  static constexpr std::string_view name = "InputPlugin";
  static constexpr std::string_view description =
      "keyboard, mouse, scroll, double clicks and resizes as plain InputState";
  static constexpr std::array<std::string_view, 1> dependencies{"WindowPlugin"};
  void build(Engine& engine);
};

// Main-world resource, copied to the render world: V toggles it in the viewer.
struct SurfaceSettings {
  bool vsync = true;
};

struct SurfaceTargetPlugin {
  static constexpr std::string_view name = "SurfaceTargetPlugin";
  static constexpr std::string_view description =
      "the window's WebGPU surface as RenderTarget (FIFO or Immediate/Mailbox), presented in "
      "PostDraw";
  static constexpr std::array<std::string_view, 3> dependencies{"WindowPlugin", "GpuPlugin",
                                                                "RenderGraphPlugin"};
  bool vsync = true;
  void build(Engine& engine);
  void finish(Engine& engine);
};

// Main-world resource: the present mode in use (for the UI), updated in Extract.
struct SurfaceInfo {
  std::string present_mode;
  glm::uvec2 size{0};
};

}  // namespace stipple::viewer
