#pragma once
// Scripted input for tests and demos: `view --script FILE` replays a JSON list of input events
// at given frames, as if they came from the window (ScriptedInputPlugin adds them to the
// frame's events between polling the window and building InputState, so every plugin sees them
// the same way). Event times are the frame's on a 60 Hz clock, so double clicks do not depend on
// how fast frames render.
//
//   {"events": [
//     {"frame": 10, "move": [640, 360]},          cursor to window coordinates x, y
//     {"frame": 11, "press": "left"},             button (left, right, middle) or key down
//     {"frame": 12, "release": "left"},
//     {"frame": 13, "click": "left"},             press and release in the same frame
//     {"frame": 14, "tap": "2"},                  a key pressed and released
//     {"frame": 15, "scroll": [0, -1]}
//   ],
//   "exit": 90}                                   quit after that frame (optional)
//
// Keys: a-z, 0-9, enter, escape, tab, backspace, delete, space, shift, ctrl, alt, f1, left,
// right, up, down.
#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "stipple/platform/input.hpp"

namespace stipple {
class Engine;
}

namespace stipple::viewer {

struct ScriptEvent {
  uint64_t frame = 0;
  platform::InputEvent event;
};

struct InputScript {
  std::vector<ScriptEvent> events;  // in frame order
  uint64_t exit_frame = 0;          // 0: run on
};

// Throws stipple::Error "<name>: ..." naming what is wrong and where.
InputScript parse_input_script(std::string_view text, const std::string& name);
InputScript read_input_script(const std::filesystem::path& path);

// Main-world resource while a script plays: the UI then takes the mouse from InputState (the
// scripted cursor and buttons) instead of the system pointer, so scripted clicks reach the
// panel as they reach the scene.
struct ScriptedInputActive {};

struct ScriptedInputPlugin {
  static constexpr std::string_view name = "ScriptedInputPlugin";
  static constexpr std::string_view description =
      "replays scripted input events (view --script) as window events";
  static constexpr std::array<std::string_view, 1> dependencies{"WindowPlugin"};
  InputScript script;
  void build(Engine& engine);
};

}  // namespace stipple::viewer
