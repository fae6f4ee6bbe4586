#include "stipple/viewer/script.hpp"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <optional>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "stipple/core/error.hpp"
#include "stipple/engine/engine.hpp"
#include "stipple/engine/render_plugins.hpp"
#include "stipple/viewer/window_plugins.hpp"

namespace stipple::viewer {
namespace {

using nlohmann::json;
using platform::InputEvent;
using platform::Key;

constexpr uint64_t kMaxFrame = uint64_t(1) << 40;

std::optional<int> key_code(std::string name) {
  std::transform(name.begin(), name.end(), name.begin(),
                 [](unsigned char c) { return char(std::tolower(c)); });
  if (name.size() == 1 && name[0] >= 'a' && name[0] <= 'z') return int(Key::A) + (name[0] - 'a');
  if (name.size() == 1 && name[0] >= '0' && name[0] <= '9') return int(Key::Num0) + (name[0] - '0');
  static const std::pair<const char*, Key> kNamed[] = {
      {"enter", Key::Enter},     {"escape", Key::Escape},
      {"tab", Key::Tab},         {"backspace", Key::Backspace},
      {"delete", Key::Delete},   {"space", Key::Space},
      {"shift", Key::LeftShift}, {"ctrl", Key::LeftControl},
      {"alt", Key::LeftAlt},     {"f1", Key::F1},
      {"left", Key::Left},       {"right", Key::Right},
      {"up", Key::Up},           {"down", Key::Down}};
  for (const auto& [n, k] : kNamed)
    if (name == n) return int(k);
  return std::nullopt;
}

std::optional<int> button_code(const std::string& name) {
  if (name == "left") return 0;
  if (name == "right") return 1;
  if (name == "middle") return 2;
  return std::nullopt;
}

// Scripted events carry the frame's time on a 60 Hz clock.
double frame_time(uint64_t frame) {
  return 1e6 + double(frame) / 60.0;
}

}  // namespace

InputScript parse_input_script(std::string_view text, const std::string& name) {
  json j;
  try {
    j = json::parse(text.begin(), text.end());
  } catch (const json::exception& e) {
    const std::string what = e.what();
    const size_t at = what.find("] ");
    fail("{}: not a valid script: {}", name, at == std::string::npos ? what : what.substr(at + 2));
  }
  if (!j.is_object()) fail("{}: a script is a JSON object with an \"events\" array", name);
  InputScript script;
  if (auto exit = j.find("exit"); exit != j.end()) {
    if (!exit->is_number_unsigned() || exit->get<uint64_t>() > kMaxFrame)
      fail("{}: \"exit\" must be a frame number", name);
    script.exit_frame = exit->get<uint64_t>();
  }
  auto events = j.find("events");
  if (events == j.end() || !events->is_array())
    fail("{}: a script needs an \"events\" array", name);
  for (size_t i = 0; i < events->size(); ++i) {
    const json& e = (*events)[i];
    const std::string where = fmt::format("{}: event {}", name, i);
    if (!e.is_object()) fail("{}: must be an object", where);
    auto frame = e.find("frame");
    if (frame == e.end() || !frame->is_number_unsigned() || frame->get<uint64_t>() > kMaxFrame)
      fail("{}: needs a \"frame\" number", where);
    const uint64_t f = frame->get<uint64_t>();
    auto add = [&](InputEvent ev) {
      ev.time = frame_time(f);
      script.events.push_back({f, ev});
    };
    auto pair = [&](const char* key) {
      const json& v = e[key];
      if (!v.is_array() || v.size() != 2 || !v[0].is_number() || !v[1].is_number())
        fail("{}: \"{}\" takes [x, y]", where, key);
      const double x = v[0].get<double>(), y = v[1].get<double>();
      if (!std::isfinite(x) || !std::isfinite(y)) fail("{}: \"{}\" must be finite", where, key);
      return glm::dvec2(x, y);
    };
    auto named = [&](const char* key) {
      const json& v = e[key];
      if (!v.is_string()) fail("{}: \"{}\" takes a key or button name", where, key);
      return v.get<std::string>();
    };
    // One button or key, down and/or up.
    auto press = [&](const std::string& what, bool down, bool up) {
      if (const auto b = button_code(what)) {
        if (down) add({InputEvent::Type::MouseButton, *b, true});
        if (up) add({InputEvent::Type::MouseButton, *b, false});
        return;
      }
      const auto k = key_code(what);
      if (!k) fail("{}: unknown key or button \"{}\"", where, what);
      if (down) add({InputEvent::Type::Key, *k, true});
      if (up) add({InputEvent::Type::Key, *k, false});
    };
    size_t actions = 0;
    if (e.contains("move")) {
      add({InputEvent::Type::CursorMove, 0, false, false, pair("move")});
      ++actions;
    }
    if (e.contains("scroll")) {
      add({InputEvent::Type::Scroll, 0, false, false, pair("scroll")});
      ++actions;
    }
    if (e.contains("press")) press(named("press"), true, false), ++actions;
    if (e.contains("release")) press(named("release"), false, true), ++actions;
    if (e.contains("click")) press(named("click"), true, true), ++actions;
    if (e.contains("tap")) press(named("tap"), true, true), ++actions;
    if (actions == 0) fail("{}: nothing to do (move, scroll, press, release, click or tap)", where);
  }
  std::stable_sort(script.events.begin(), script.events.end(),
                   [](const ScriptEvent& a, const ScriptEvent& b) { return a.frame < b.frame; });
  return script;
}

InputScript read_input_script(const std::filesystem::path& path) {
  const std::string name = path.string();
  std::ifstream in(path, std::ios::binary);
  if (!in) fail("{}: cannot open: {}", name, std::strerror(errno));
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (text.size() > (64u << 20)) fail("{}: too large for a script", name);
  return parse_input_script(text, name);
}

namespace {

// Main-world resource.
struct ScriptState {
  InputScript script;
  size_t next = 0;
  uint64_t frame = 0;
};

void play_script(Registry& main) {
  auto& s = main.resource<ScriptState>();
  auto& window = main.resource<WindowState>();
  while (s.next < s.script.events.size() && s.script.events[s.next].frame <= s.frame)
    window.events.push_back(s.script.events[s.next++].event);
  if (s.script.exit_frame > 0 && s.frame >= s.script.exit_frame)
    main.resource<AppExit>().requested = true;
  ++s.frame;
}

}  // namespace

void ScriptedInputPlugin::build(Engine& engine) {
  engine.main().insert_resource(ScriptState{script});
  engine.main().insert_resource(ScriptedInputActive{});
  engine.add_system(MainStage::Input, play_script, "play_script");
}

}  // namespace stipple::viewer
