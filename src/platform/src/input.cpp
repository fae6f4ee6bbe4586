#include "stipple/platform/input.hpp"

#include <glm/geometric.hpp>

namespace stipple::platform {

void apply_events(InputState& s, std::span<const InputEvent> events) {
  s.key_pressed.fill(false);
  s.key_released.fill(false);
  s.button_pressed.fill(false);
  s.button_released.fill(false);
  s.cursor_delta = {0.0, 0.0};
  s.scroll = {0.0, 0.0};
  s.double_clicked = false;
  s.resized = false;
  for (const InputEvent& e : events) {
    switch (e.type) {
      case InputEvent::Type::Key:
        if (e.code < 0 || size_t(e.code) >= kKeyCount) break;
        if (e.down && !e.repeat) s.key_pressed[size_t(e.code)] = true;
        if (!e.down) s.key_released[size_t(e.code)] = true;
        s.key_down[size_t(e.code)] = e.down;
        break;
      case InputEvent::Type::MouseButton:
        if (e.code < 0 || size_t(e.code) >= kMouseButtonCount) break;
        s.button_down[size_t(e.code)] = e.down;
        (e.down ? s.button_pressed : s.button_released)[size_t(e.code)] = true;
        if (e.down && e.code == int(MouseButton::Left)) {
          if (e.time - s.last_click_time <= kDoubleClickSeconds &&
              glm::distance(s.cursor, s.last_click_position) <= kDoubleClickPixels) {
            s.double_clicked = true;
            s.double_click_position = s.cursor;
            s.last_click_time = -1e9;  // a third click starts a new pair
          } else {
            s.last_click_time = e.time;
            s.last_click_position = s.cursor;
          }
        }
        break;
      case InputEvent::Type::CursorMove:
        s.cursor_delta += e.value - s.cursor;
        s.cursor = e.value;
        break;
      case InputEvent::Type::Scroll:
        s.scroll += e.value;
        break;
      case InputEvent::Type::Resize:
        s.framebuffer_size = glm::uvec2(e.value);
        s.resized = true;
        break;
      case InputEvent::Type::Close:
        s.close_requested = true;
        break;
      case InputEvent::Type::Focus:
        s.focused = e.down;
        if (!e.down) {  // keys released while unfocused never report: drop them all
          s.key_down.fill(false);
          s.button_down.fill(false);
        }
        break;
    }
  }
}

}  // namespace stipple::platform
