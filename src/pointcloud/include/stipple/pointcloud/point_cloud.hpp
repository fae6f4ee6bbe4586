#pragma once
// Points prepared for rendering: chunks of float positions relative to a double-precision
// chunk origin (world space, Y-up) with the attributes the colour modes need, packed. Colouring
// happens in the shader (point_renderer), so switching colour modes needs no re-upload.
#include <array>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include "stipple/io/point_batch.hpp"
#include "stipple/math/aabb.hpp"
#include "stipple/math/camera.hpp"

namespace stipple::io {
struct SceneParams;
}

namespace stipple::io {
class LasReader;
}

namespace stipple::pc {

enum class ColorMode { Auto, Rgb, Intensity, Classification, Elevation, ReturnNumber, Constant };
ColorMode parse_color_mode(const std::string& name);
const char* color_mode_name(ColorMode mode);

struct PointChunk {
  glm::dvec3 origin{0.0};  // world space (Y-up), double
  // 20 bytes, read by the shaders as `Point` (vertex pulling from a storage buffer).
  struct Vertex {
    float x, y, z;  // relative to origin
    // 8-bit RGB from the source (R in the low byte); 0 when it has none. Alpha counts only in
    // clouds with CloudAttributes::has_translucent.
    uint32_t rgba;
    // intensity (bits 0-15), classification (16-23), return number (24-27), number of
    // returns (28-31).
    uint32_t attributes;
  };
  std::vector<Vertex> vertices;
  Aabb bounds;           // world space (Y-up), of this chunk's points
  double spacing = 0.0;  // mean point spacing (metres) over the chunk's horizontal extent
  // Attributes beyond the packed word, for GPS-time and point-source filters and inspection;
  // kept only when the cloud is loaded with keep_extras (the viewer), so the default path pays
  // nothing. GPS time is relative to the chunk's gps_origin (a chunk spans seconds of a survey,
  // so a float keeps microseconds), the word holds the point source ID (bits 0-15), the flags
  // of io::PointBatch (16-23) and user data (24-31).
  struct Extra {
    float gps;
    uint32_t word;
  };
  std::vector<Extra> extras;  // empty, or one per vertex
  double gps_origin = 0.0;
  // Index of the chunk's first point among all input points (files in order, records in
  // order): with PointCloud::file_first_point it finds a point's record again.
  uint64_t first_point = 0;
};
static_assert(sizeof(PointChunk::Vertex) == 20);
static_assert(sizeof(PointChunk::Extra) == 8);

uint32_t pack_attributes(uint16_t intensity, uint8_t classification, uint8_t return_number,
                         uint8_t number_of_returns);
// Point i of a batch packed as a Vertex holds it: 8-bit RGB (`rgb_bits` says whether the batch
// holds 8- or 16-bit values; 0 without RGB) and the attribute word (defaults for missing ones:
// class 1, single return).
uint32_t batch_rgba(const io::PointBatch& batch, size_t i, int rgb_bits);
// A stored RGB (8- or 16-bit as rgb_bits says) as batch_rgba packs it.
uint32_t rgba_of(glm::u16vec3 rgb, int rgb_bits);
uint32_t batch_attributes(const io::PointBatch& batch, size_t i);

struct CloudAttributes {
  // Which attributes the source has (a colour mode without its attribute falls back).
  bool has_rgb = false, has_intensity = false, has_classification = false, has_returns = false;
  // Every source's RGB is one colour (io::LasHeader::rgb_uniform: all 0, as some writers fill
  // the fields): Auto does not take it for colour; an explicit RGB mode still shows it.
  bool rgb_uniform = false;
  // Some point's RGBA alpha is under 255 (3D Tiles content whose file gives alpha: pnts RGBA,
  // CONSTANT_RGBA, glb COLOR_0 under BLEND). Only such clouds read the vertices' alpha: in the
  // RGB mode their translucent points are drawn alpha blended after the opaque ones; other
  // clouds (LAS: alpha 0 where there is no RGB) never look at it and run the opaque passes only.
  bool has_translucent = false;
  // 2nd and 98th percentiles over a sample of the points (finish_cloud): default ramp ranges
  // that ignore outliers (a stray bird or a pit would otherwise flatten the ramp).
  glm::dvec2 elevation_percentiles{0.0, 1.0};  // source Z (= world Y)
  glm::dvec2 intensity_percentiles{0.0, 255.0};
};

struct PointCloud {
  std::vector<PointChunk> chunks;
  Aabb source_bounds;  // in the source frame (Z-up: projected CRS units, or local ENU metres)
  Aabb world_bounds;   // Y-up world space
  uint64_t point_count = 0;
  bool geographic = false;  // source was lon/lat: positions converted to a local ENU frame
  std::optional<glm::dvec3> enu_origin;  // geographic: the ENU frame's origin (lon, lat, h)
  CloudAttributes attributes;
  bool keep_extras = false;  // append_batch fills PointChunk::extras
  // The inputs, and the index of each one's first point (for finding a record again).
  std::vector<std::filesystem::path> files;
  std::vector<uint64_t> file_first_point;
};

// The colour mode actually shown for this cloud: Auto becomes RGB when the source has colours
// (not one colour everywhere), elevation otherwise; modes whose attribute is missing fall back
// to elevation.
ColorMode resolve_color_mode(const CloudAttributes& attributes, ColorMode requested);

struct LoadOptions {
  size_t chunk_points = 1 << 20;
  bool progress = true;
  bool keep_extras = false;  // PointChunk::extras (GPS time, point source, flags, user data)
  // Read only about this many points spread across the whole of the inputs (0: all): a first
  // image of a large file at once (render --progressive). See read_las_sample.
  uint64_t sample = 0;
};

// Reads about `want` points spread across the whole file behind `reader`, handing each batch to
// `take` in file order. LAZ with fixed-size chunks: the first points of every chunk (decoding
// starts at each chunk through the chunk table, nothing is decoded twice); otherwise runs of
// records at a stride. Returns the points read; `want` >= the file's points reads them all.
uint64_t read_las_sample(io::LasReader& reader, uint64_t want,
                         const std::function<void(io::PointBatch&)>& take);

// Adds the chunks' points to a view fit (world space): the outermost chunks first, and chunks
// whose bounds cannot widen the fit are not read, so a large cloud reads few of its points.
void fit_chunks(ViewFit& fit, std::span<const PointChunk* const> chunks);
void fit_cloud(ViewFit& fit, const PointCloud& cloud);

// Reads LAS/LAZ/COPC files chunk by chunk into one cloud. Throws stipple::Error.
PointCloud load_point_cloud(const std::vector<std::filesystem::path>& files,
                            const LoadOptions& options);

// Appends a batch of source points (Z-up) to the cloud. `rgb_bits` says whether the batch's
// RGB holds 8- or 16-bit values. Call finish_cloud() after the last batch.
void append_batch(PointCloud& cloud, const io::PointBatch& batch, int rgb_bits,
                  size_t chunk_points);
// The colour ramps' default range: the `lo` and `hi` quantiles (0.02 and 0.98) of sampled values,
// each sample standing for `weights[i]` points (none: one each); a flat sample gets a unit
// range. LAS input and streamed tiles both take their ramps from it.
glm::dvec2 percentile_range(std::vector<double> values, std::vector<double> weights, double lo,
                            double hi);

// Computes per-chunk spacing and the cloud's attribute percentiles.
void finish_cloud(PointCloud& cloud);

// The built-in procedural scene as a cloud, generated in parallel (1M-point chunks).

// Chunks hold at most chunk_points points (capped at 1M, the generation block).
PointCloud generate_scene_cloud(const io::SceneParams& params, size_t chunk_points = 1 << 20,
                                bool keep_extras = false);

// The packed extras word of point i of a batch (PointChunk::Extra::word).
uint32_t batch_extra_word(const io::PointBatch& batch, size_t i);

uint32_t pack_rgba(uint8_t r, uint8_t g, uint8_t b, uint8_t a = 255);

// ASPRS LAS 1.4 standard classes 0-18 (then "unclassified" up to 31), RGB in 0..1.
const std::array<glm::vec3, 32>& classification_palette();

// What a colour mode needs besides the points: the compute rasterizer's shading uniforms (the
// billboard path's point_color applies the same, from its frame uniforms).
struct PointShading {
  ColorMode mode = ColorMode::Auto;          // resolved per cloud or tile (resolve_color_mode)
  glm::dvec2 elevation_range{0.0, 1.0};      // world Y (the source elevation)
  glm::dvec2 intensity_range{0.0, 65535.0};  // grey ramp
  glm::vec3 constant_color{1.0f, 1.0f, 1.0f};
};

}  // namespace stipple::pc
