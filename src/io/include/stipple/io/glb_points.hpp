#pragma once
// Point primitives (mode POINTS) of a glTF 2.0 binary (GLB) tile, as 3D Tiles 1.1 uses them:
// node transforms applied, then the glTF Y-up to 3D Tiles Z-up rotation, then CESIUM_RTC.
// Accessors may be quantized (KHR_mesh_quantization) and buffer views meshopt-compressed
// (EXT_meshopt_compression).
#include <functional>
#include <span>
#include <string>
#include <vector>

#include "stipple/io/pnts.hpp"

namespace stipple::io {

// Fetches an external buffer by URI relative to the glb (nullptr: external buffers refused).
using BufferResolver = std::function<std::vector<uint8_t>(const std::string& uri)>;

// Accepts GLB, or glTF JSON whose buffers are data: URIs or resolvable. Throws stipple::Error.
PointContent decode_glb_points(std::span<const uint8_t> data, const std::string& name,
                               const DecodeLimits& limits = {},
                               const BufferResolver& resolver = nullptr);

}  // namespace stipple::io
