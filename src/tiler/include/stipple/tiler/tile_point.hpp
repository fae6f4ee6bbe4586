#pragma once
// The tiler's point record: what a tile keeps of a LAS point, in the tileset's local frame.
// Plain and fixed-size so that chunks go to and from temporary files as raw bytes.
#include <cstdint>
#include <span>
#include <vector>

#include <glm/common.hpp>
#include <glm/vec3.hpp>

namespace stipple::tiler {

struct TilePoint {
  double x, y, z;   // local east-north-up metres (see geo_frame.hpp), double: never loses input
  double gps_time;  // seconds as stored in LAS; 0 when the input has none
  uint16_t intensity;
  uint8_t r, g, b;  // 8-bit colour (16-bit input scaled down)
  uint8_t classification;
  uint8_t return_number;
  uint8_t pad;
};
static_assert(sizeof(TilePoint) == 40);

// How content is compressed: glb with EXT_meshopt_compression, pnts with
// 3DTILES_draco_point_compression (glTF's Draco extension does not define point primitives).
enum class Compression { None, Meshopt, Draco };

// Which attributes a content file carries and how precisely positions must be kept.
struct ContentOptions {
  Compression compression = Compression::None;
  bool rgb = true;
  bool gps_time = true;
  // Finest position step of the inputs in metres (LAS scale): integer quantization is used
  // only where its step does not exceed this, so no input precision is lost.
  double precision = 0.001;
};

struct Box {
  glm::dvec3 min{1e300}, max{-1e300};
  bool empty() const { return min.x > max.x; }
  void add(const glm::dvec3& p) {
    min = glm::min(min, p);
    max = glm::max(max, p);
  }
  void add(const Box& b) {
    if (b.empty()) return;
    add(b.min);
    add(b.max);
  }
};

Box bounds_of(std::span<const TilePoint> points);

}  // namespace stipple::tiler
