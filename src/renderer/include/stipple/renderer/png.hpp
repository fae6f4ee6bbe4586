#pragma once
#include <filesystem>

#include "stipple/renderer/gpu.hpp"

namespace stipple::gpu {
// Writes RGBA8 as PNG (through a temporary file renamed into place, so a failed write never
// leaves a truncated image behind). Throws stipple::Error.
void write_png(const std::filesystem::path& path, const Image& image);
Image read_png(const std::filesystem::path& path);
}  // namespace stipple::gpu
