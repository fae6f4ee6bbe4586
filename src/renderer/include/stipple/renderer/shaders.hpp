#pragma once
// WGSL sources by file name: embedded at build time, or read from STIPPLE_SHADER_DIR when that
// is set (edit shaders without rebuilding).
#include <string>
#include <string_view>

namespace stipple::gpu {

// Throws stipple::Error when no shader of that name exists.
std::string shader_source(std::string_view name);

}  // namespace stipple::gpu
