#pragma once
// A GLFW window without a client API (WebGPU presents through a surface the renderer makes from
// the native handles). GLFW calls must come from the main thread: create, poll and destroy there.
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <glm/vec2.hpp>

#include "stipple/platform/input.hpp"

struct GLFWwindow;

namespace stipple::platform {

struct WindowOptions {
  std::string title = "stipple";
  uint32_t width = 1280, height = 720;  // screen coordinates
  bool visible = true;
  bool resizable = true;
};

// What a WebGPU surface is made from. Only X11 for now (also what XWayland offers).
struct NativeWindow {
  void* x11_display = nullptr;  // Display*
  uint64_t x11_window = 0;      // Window (XID)
};

struct Window;  // owns the GLFWwindow and its pending events

void destroy_window(Window* window);
struct WindowDeleter {
  void operator()(Window* w) const { destroy_window(w); }
};
using WindowPtr = std::unique_ptr<Window, WindowDeleter>;
// Initialises GLFW on first use. Throws stipple::Error when no display can be opened.
WindowPtr make_window(const WindowOptions& options);

// Processes GLFW's event queue and returns the events since the last call (in order). With
// `wait_seconds` > 0 it sleeps until an event arrives or the time is up (minimised windows).
std::vector<InputEvent> poll_events(Window& window, double wait_seconds = 0);
GLFWwindow* glfw_window(Window& window);  // for libraries that speak GLFW (the UI backend)
NativeWindow native_window(Window& window);
glm::uvec2 framebuffer_size(Window& window);  // pixels; 0x0 while minimised
glm::uvec2 window_size(Window& window);       // screen coordinates (cursor positions)
bool minimised(Window& window);
void set_title(Window& window, const std::string& title);
double time_seconds();

}  // namespace stipple::platform
