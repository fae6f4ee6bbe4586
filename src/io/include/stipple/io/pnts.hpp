#pragma once
// Decoded point content of a 3D Tiles tile (pnts, or glb point primitives): structure-of-arrays,
// positions as floats relative to a double-precision centre, in the tile's frame (Z-up).
#include <cstdint>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "stipple/io/splats.hpp"

namespace stipple::io {

// A per-point attribute from a batch table (or a glTF vertex attribute): `components` values
// per point, converted to double (exact for every 3D Tiles component type up to 32 bits).
struct PointAttribute {
  std::string component_type;  // "UNSIGNED_BYTE", "FLOAT", ... ("JSON" for JSON arrays)
  int components = 1;
  std::vector<double> values;
};

struct PointContent {
  size_t point_count = 0;
  glm::dvec3 center{0.0};            // RTC_CENTER (+ quantized volume offset), in the tile frame
  std::vector<glm::vec3> positions;  // relative to center
  std::vector<uint32_t> rgba;        // packed, R in the low byte; empty when the tile has none
  bool constant_color = false;       // rgba came from CONSTANT_RGBA
  std::vector<glm::vec3> normals;    // empty when absent
  std::vector<uint32_t> batch_ids;   // empty when absent
  // rgba's alpha means something (pnts RGBA and CONSTANT_RGBA; glb COLOR_0 under a BLEND or MASK
  // material, MASK already applied at its cutoff: 0 or 255). Points under full opacity are drawn
  // translucent (alpha blended) in the RGB colour mode; fully transparent ones (alpha 0) are
  // not drawn. Without it, alpha is 255 whatever the file holds.
  bool alpha = false;
  uint32_t batch_length = 0;
  std::map<std::string, PointAttribute> attributes;
  std::vector<std::string> warnings;  // unknown semantics and extensions, skipped properties
  std::string format;                 // "pnts", "pnts+draco", "glb"
  // Non-empty for content that holds nothing stipple draws (meshes: b3dm, i3dm, glb triangles):
  // what it is, for a warning. Such content decodes to no points instead of failing its tile.
  std::string not_drawn;
  // Gaussian splats (a glb with KHR_gaussian_splatting, as `stipple tile` writes from splat
  // files): the tile's content is these, not points (point_count counts them, positions stay
  // empty), for a splat consumer (tiles3d's splat stream); point paths skip such content.
  std::shared_ptr<const SplatSet> splats;

  // Resident size, for the cache's memory budget.
  uint64_t memory_bytes() const;
};

// Limits that keep a hostile file from allocating without bound.
struct DecodeLimits {
  uint64_t max_points = 50'000'000;
  uint64_t max_json_bytes = 64ull << 20;
};

// Decodes a pnts tile. Throws stipple::Error naming `name` and the problem.
PointContent decode_pnts(std::span<const uint8_t> data, const std::string& name,
                         const DecodeLimits& limits = {});

// Shared by the pnts and glb decoders: little-endian reads bounded by a span.
namespace detail {
uint32_t read_u32(std::span<const uint8_t> data, size_t offset);
uint64_t read_u64(std::span<const uint8_t> data, size_t offset);
// Bytes per component of a 3D Tiles componentType name; 0 when unknown.
int component_size(const std::string& type);
double read_component(const uint8_t* p, const std::string& type);
int type_components(const std::string& type);  // SCALAR 1 .. VEC4 4; 0 when unknown
}  // namespace detail

}  // namespace stipple::io
