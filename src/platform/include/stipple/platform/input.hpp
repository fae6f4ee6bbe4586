#pragma once
// Input as plain data: the window collects raw events, apply_events() folds a frame's events into
// an InputState (held keys and buttons, what was pressed or released this frame, cursor motion,
// scroll, double clicks, resizes). No GLFW here, so camera logic is testable without a window.
#include <array>
#include <cstdint>
#include <span>

#include <glm/vec2.hpp>

namespace stipple::platform {

// Key codes: GLFW's values (printable keys are their ASCII capitals).
enum class Key : uint16_t {
  Space = 32,
  Num0 = 48,
  Num1,
  Num2,
  Num3,
  Num4,
  Num5,
  Num6,
  Num7,
  Num8,
  Num9,
  A = 65,
  B,
  C,
  D,
  E,
  F,
  G,
  H,
  I,
  J,
  K,
  L,
  M,
  N,
  O,
  P,
  Q,
  R,
  S,
  T,
  U,
  V,
  W,
  X,
  Y,
  Z,
  Escape = 256,
  Enter,
  Tab,
  Backspace,
  Insert,
  Delete,
  Right = 262,
  Left,
  Down,
  Up,
  F1 = 290,
  LeftShift = 340,
  LeftControl,
  LeftAlt,
  LeftSuper,
  RightShift,
  RightControl,
  RightAlt,
};
inline constexpr size_t kKeyCount = 349;  // GLFW_KEY_LAST + 1

enum class MouseButton : uint8_t { Left = 0, Right = 1, Middle = 2 };
inline constexpr size_t kMouseButtonCount = 3;

struct InputEvent {
  enum class Type : uint8_t { Key, MouseButton, CursorMove, Scroll, Resize, Close, Focus };
  Type type = Type::Key;
  int code = 0;           // key code or mouse button
  bool down = false;      // key/button pressed (true) or released; focus gained
  bool repeat = false;    // key auto-repeat
  glm::dvec2 value{0.0};  // cursor position (window coordinates), scroll offsets, or new size
  double time = 0;        // seconds (glfwGetTime)
};

struct InputState {
  std::array<bool, kKeyCount> key_down{}, key_pressed{}, key_released{};
  std::array<bool, kMouseButtonCount> button_down{}, button_pressed{}, button_released{};
  glm::dvec2 cursor{0.0};        // window coordinates, origin top left
  glm::dvec2 cursor_delta{0.0};  // motion this frame
  glm::dvec2 scroll{0.0};        // wheel offsets this frame (y > 0: away from the user)
  bool double_clicked = false;   // left button, this frame
  glm::dvec2 double_click_position{0.0};
  bool resized = false;  // the framebuffer size changed this frame
  glm::uvec2 framebuffer_size{0};
  bool close_requested = false;
  bool focused = true;

  // Double-click detection: the last left press.
  double last_click_time = -1e9;
  glm::dvec2 last_click_position{0.0};

  bool down(Key k) const { return key_down[size_t(k)]; }
  bool pressed(Key k) const { return key_pressed[size_t(k)]; }
  bool down(MouseButton b) const { return button_down[size_t(b)]; }
  bool pressed(MouseButton b) const { return button_pressed[size_t(b)]; }
  bool shift() const { return down(Key::LeftShift) || down(Key::RightShift); }
};

// Two left presses at most this far apart in time (seconds) and space (pixels) are a double click.
inline constexpr double kDoubleClickSeconds = 0.35;
inline constexpr double kDoubleClickPixels = 4.0;

// Clears the per-frame fields, then applies the events in order.
void apply_events(InputState& state, std::span<const InputEvent> events);

}  // namespace stipple::platform
