#pragma once
// TimePlugin: the frame counter and clock of the main world, copied to the render world.
#include <chrono>
#include <cstdint>
#include <string_view>

#include "stipple/engine/registry.hpp"

namespace stipple {

class Engine;

// Main-world resource, advanced at the start of Input.
struct Time {
  uint64_t frame = 0;          // index of the current frame, 0 for the first
  double delta_seconds = 0;    // since the previous frame (0 on the first)
  double elapsed_seconds = 0;  // sum of deltas
  double fixed_delta = 0;      // > 0: every frame advances by this (deterministic runs, tests)
  std::chrono::steady_clock::time_point last{};
};

// Render-world resource: the Time of the frame being drawn.
struct RenderTime {
  uint64_t frame = 0;
  double delta_seconds = 0;
  double elapsed_seconds = 0;
};

void advance_time(Registry& main);
void extract_time(Registry& main);

struct TimePlugin {
  static constexpr std::string_view name = "TimePlugin";
  static constexpr std::string_view description = "frame counter and clock (Time, RenderTime)";
  double fixed_delta = 0;
  void build(Engine& engine);
};

}  // namespace stipple
