#pragma once
// Points prepared for rendering: chunks of float positions relative to a double-precision
// chunk origin (world space, Y-up) with packed RGBA8 colours.
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "io/point_batch.hpp"
#include "math/aabb.hpp"

namespace stipple::pc {

enum class ColorMode { Auto, Rgb, Intensity, Classification, Elevation, ReturnNumber };
ColorMode parse_color_mode(const std::string& name);

struct PointChunk {
  glm::dvec3 origin{0.0};  // world space (Y-up), double
  struct Vertex {
    float x, y, z;  // relative to origin
    uint32_t rgba;  // R in the low byte
  };
  std::vector<Vertex> vertices;
};

struct PointCloud {
  std::vector<PointChunk> chunks;
  Aabb source_bounds;  // in the source frame (Z-up: projected CRS units, or local ENU metres)
  Aabb world_bounds;   // Y-up world space
  uint64_t point_count = 0;
  bool geographic = false;   // source was lon/lat: positions converted to a local ENU frame
  std::string color_source;  // what the colours show, for reports
};

struct LoadOptions {
  ColorMode color = ColorMode::Auto;
  size_t chunk_points = 1 << 20;
  bool progress = true;
};

// Reads LAS/LAZ/COPC files chunk by chunk into one cloud. Throws stipple::Error.
PointCloud load_point_cloud(const std::vector<std::filesystem::path>& files,
                            const LoadOptions& options);

// Appends a batch of source points (Z-up) to the cloud, colouring them. `rgb_bits` says
// whether the batch's RGB holds 8- or 16-bit values; `elevation_range` scales the ramp.
void append_batch(PointCloud& cloud, const io::PointBatch& batch, ColorMode mode, int rgb_bits,
                  glm::dvec2 elevation_range, size_t chunk_points);

uint32_t pack_rgba(uint8_t r, uint8_t g, uint8_t b, uint8_t a = 255);

}  // namespace stipple::pc
