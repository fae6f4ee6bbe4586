#include "stipple/platform/window.hpp"

#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>

// GLFW's X11 accessors, declared here rather than through glfw3native.h, which pulls in the X11
// extension headers (libxrandr-dev) for two functions. Display* and Window (an XID, unsigned
// long) are passed as what they are at the ABI level.
extern "C" {
void* glfwGetX11Display(void);
unsigned long glfwGetX11Window(GLFWwindow* window);
}

#include <algorithm>
#include <mutex>
#include <utility>

#include "stipple/core/error.hpp"
#include "stipple/core/log.hpp"

namespace stipple::platform {

struct Window {
  GLFWwindow* handle = nullptr;
  std::vector<InputEvent> events;  // filled by the callbacks during glfwPollEvents
};

namespace {

std::once_flag g_init_once;
bool g_initialised = false;
std::string g_init_error;

void on_glfw_error(int code, const char* message) {
  g_init_error = message ? message : "";
  STIPPLE_DEBUG("GLFW error {}: {}", code, g_init_error);
}

Window& owner(GLFWwindow* handle) {
  return *static_cast<Window*>(glfwGetWindowUserPointer(handle));
}

void push(GLFWwindow* handle, InputEvent e) {
  e.time = glfwGetTime();
  owner(handle).events.push_back(e);
}

void on_key(GLFWwindow* w, int key, int, int action, int) {
  if (key == GLFW_KEY_UNKNOWN) return;
  push(w, {InputEvent::Type::Key, key, action != GLFW_RELEASE, action == GLFW_REPEAT});
}
void on_mouse_button(GLFWwindow* w, int button, int action, int) {
  push(w, {InputEvent::Type::MouseButton, button, action == GLFW_PRESS});
}
void on_cursor(GLFWwindow* w, double x, double y) {
  push(w, {InputEvent::Type::CursorMove, 0, false, false, {x, y}});
}
void on_scroll(GLFWwindow* w, double x, double y) {
  push(w, {InputEvent::Type::Scroll, 0, false, false, {x, y}});
}
void on_framebuffer_size(GLFWwindow* w, int width, int height) {
  push(w, {InputEvent::Type::Resize, 0, false, false, {double(width), double(height)}});
}
void on_close(GLFWwindow* w) {
  push(w, {InputEvent::Type::Close});
}
void on_focus(GLFWwindow* w, int focused) {
  push(w, {InputEvent::Type::Focus, 0, focused == GLFW_TRUE});
}

}  // namespace

WindowPtr make_window(const WindowOptions& options) {
  std::call_once(g_init_once, [] {
    glfwSetErrorCallback(on_glfw_error);
#if GLFW_VERSION_MAJOR * 100 + GLFW_VERSION_MINOR >= 304
    glfwInitHint(GLFW_PLATFORM, GLFW_PLATFORM_X11);  // our surfaces are X11 ones
#endif
    g_initialised = glfwInit() == GLFW_TRUE;
  });
  if (!g_initialised)
    fail("cannot open a window: GLFW failed to initialise ({}); is DISPLAY set?", g_init_error);
  glfwDefaultWindowHints();
  glfwWindowHint(GLFW_CLIENT_API, GLFW_NO_API);  // WebGPU, not OpenGL
  glfwWindowHint(GLFW_VISIBLE, options.visible ? GLFW_TRUE : GLFW_FALSE);
  glfwWindowHint(GLFW_RESIZABLE, options.resizable ? GLFW_TRUE : GLFW_FALSE);
  WindowPtr window(new Window);
  window->handle = glfwCreateWindow(int(options.width), int(options.height), options.title.c_str(),
                                    nullptr, nullptr);
  if (!window->handle)
    fail("cannot create a {}x{} window: {}", options.width, options.height, g_init_error);
  glfwSetWindowUserPointer(window->handle, window.get());
  glfwSetKeyCallback(window->handle, on_key);
  glfwSetMouseButtonCallback(window->handle, on_mouse_button);
  glfwSetCursorPosCallback(window->handle, on_cursor);
  glfwSetScrollCallback(window->handle, on_scroll);
  glfwSetFramebufferSizeCallback(window->handle, on_framebuffer_size);
  glfwSetWindowCloseCallback(window->handle, on_close);
  glfwSetWindowFocusCallback(window->handle, on_focus);
  // The first frame starts from the real cursor and size, not from zero.
  double x = 0, y = 0;
  glfwGetCursorPos(window->handle, &x, &y);
  window->events.push_back({InputEvent::Type::CursorMove, 0, false, false, {x, y}});
  glm::uvec2 fb = framebuffer_size(*window);
  window->events.push_back(
      {InputEvent::Type::Resize, 0, false, false, {double(fb.x), double(fb.y)}});
  return window;
}

void destroy_window(Window* window) {
  if (!window) return;
  if (window->handle) glfwDestroyWindow(window->handle);
  delete window;
}

std::vector<InputEvent> poll_events(Window& window, double wait_seconds) {
  if (wait_seconds > 0)
    glfwWaitEventsTimeout(wait_seconds);
  else
    glfwPollEvents();
  return std::exchange(window.events, {});
}

GLFWwindow* glfw_window(Window& window) {
  return window.handle;
}

NativeWindow native_window(Window& window) {
  NativeWindow n;
  n.x11_display = glfwGetX11Display();
  n.x11_window = uint64_t(glfwGetX11Window(window.handle));
  if (!n.x11_display || !n.x11_window) fail("the window has no X11 handle (X11 is required)");
  return n;
}

glm::uvec2 framebuffer_size(Window& window) {
  int w = 0, h = 0;
  glfwGetFramebufferSize(window.handle, &w, &h);
  return {uint32_t(std::max(w, 0)), uint32_t(std::max(h, 0))};
}

glm::uvec2 window_size(Window& window) {
  int w = 0, h = 0;
  glfwGetWindowSize(window.handle, &w, &h);
  return {uint32_t(std::max(w, 0)), uint32_t(std::max(h, 0))};
}

bool minimised(Window& window) {
  return glfwGetWindowAttrib(window.handle, GLFW_ICONIFIED) == GLFW_TRUE ||
         framebuffer_size(window) == glm::uvec2(0);
}

void set_title(Window& window, const std::string& title) {
  glfwSetWindowTitle(window.handle, title.c_str());
}

double time_seconds() {
  return glfwGetTime();
}

}  // namespace stipple::platform
