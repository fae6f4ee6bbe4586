#pragma once
// Main-world resource: the size in pixels of the target the frame is drawn into, for whatever
// needs it before the render world knows (screen-space error, framing, picking). The target's
// plugin keeps it: HeadlessTargetPlugin sets it once, a window's plugin on every resize.
#include <cstdint>

namespace stipple {

struct Viewport {
  uint32_t width = 0, height = 0;
  bool valid() const { return width > 0 && height > 0; }
  double aspect() const { return valid() ? double(width) / double(height) : 1.0; }
};

}  // namespace stipple
