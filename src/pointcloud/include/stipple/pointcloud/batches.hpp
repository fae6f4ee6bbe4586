#pragma once
// Points grouped into batches for the compute rasterizer (seed 001, sections 3.1, 3.3, 3.5):
// consecutive points of a spatially ordered (Morton or Hilbert) list form a batch with its own
// bounding box; positions are quantized to 30 bits per axis relative to that box and split into
// three 32-bit words (coarse, medium, fine: 10 bits per axis each) kept in separate arrays, so a
// renderer loads only the bits a batch needs on screen. Colours are a fourth array.
//
// Batches have a first index and a count of their own, so LOD nodes (batches of varying size)
// fit the same layout. Plain CPU code, testable without a device.
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "stipple/core/default_init.hpp"
#include "stipple/math/aabb.hpp"
#include "stipple/math/camera.hpp"
#include "stipple/pointcloud/point_cloud.hpp"

namespace stipple {
class ThreadPool;
}

namespace stipple::io {
struct SceneParams;
}

namespace stipple::pc {

constexpr uint32_t kBatchPoints = 10'240;  // 128 threads x 80 points (seed 001, section 3.2)

enum class SpatialOrder { None, Morton, Hilbert };
SpatialOrder parse_spatial_order(const std::string& name);

// 3D space-filling curve keys of 21-bit cell coordinates (63-bit keys).
uint64_t morton_key(uint32_t x, uint32_t y, uint32_t z);
uint64_t hilbert_key(uint32_t x, uint32_t y, uint32_t z);
// The 30-bit Hilbert index of a 30-bit Morton code (10 bits per axis), by a state table walked
// three bits at a time (seed 002 after its ref. [41]): equal to the top 30 bits of hilbert_key
// for the same cell, without Skilling's per-bit loops.
uint32_t hilbert_from_morton(uint32_t morton30);

struct Batch {
  glm::dvec3 min{0.0};   // world space (Y-up), double: made camera-relative per frame
  glm::dvec3 size{0.0};  // box extent; the quantization grid spans it
  uint64_t first = 0;    // index of the first point in the cloud's arrays
  uint32_t count = 0;
};

// Per-point words, filled in parallel by the batch writer (no zeroing first).
using PointWords = UninitVector<uint32_t>;

struct BatchedCloud {
  std::vector<Batch> batches;
  // One entry per point, in batch order (struct of arrays).
  PointWords coarse, medium, fine;  // 10 bits per axis each: x | y << 10 | z << 20
  PointWords color;                 // RGBA8 from the source, R in the low byte (0: none)
  // Intensity, class and returns packed as PointChunk::Vertex::attributes: the rasterizer
  // shades the visible points from these words and `color` in the chosen colour mode.
  PointWords attributes;
  Aabb world_bounds;
  uint64_t point_count() const { return color.size(); }
};

// Quantizes p to 30 bits per axis inside [min, min + size] (eq. 1 of seed 001) and splits the
// bits into the three words.
struct QuantizedPoint {
  uint32_t coarse, medium, fine;
};
// The coarse word's bits 30-31 are free (three 10-bit axes). Bit 30 marks a translucent point
// (alpha under 255) in clouds batched with BatchingOptions::mark_translucent: the rasterizer's
// opaque passes skip it and its translucent pass draws it without reading its colour first
// (compute_raster.hpp). Every reader of the positions masks the axes.
constexpr uint32_t kTranslucentBit = 1u << 30;
QuantizedPoint quantize(const glm::dvec3& p, const glm::dvec3& min, const glm::dvec3& size);
// The position the renderer reconstructs from `bits` (10, 20 or 30) bits per axis: the centre of
// the quantization cell (exact for 30 bits up to half a 2^-30 cell).
glm::dvec3 dequantize(const QuantizedPoint& q, int bits, const glm::dvec3& min,
                      const glm::dvec3& size);

// The sort key of batching: the 30-bit Morton (or Hilbert) index of the point's cell in a grid
// of 1024^3 cubes over the cube of edge `extent` at `min` (cells past the grid are clamped).
// Cells that hold more than a batch are sorted again inside their own box (see append_batches).
uint32_t curve_key30(const glm::dvec3& p, const glm::dvec3& min, double extent, SpatialOrder order);

// The threads that batch large clouds and copy them to the GPU (one per core).
ThreadPool& batching_pool();

// Where the time of a batching went (seconds), for benchmarks.
struct BatchBuildStats {
  double bounds_s = 0, keys_s = 0, sort_s = 0, refine_s = 0, write_s = 0;
  uint64_t refined_cells = 0;  // cells holding more than a batch, sorted again
};

struct BatchingOptions {
  SpatialOrder order = SpatialOrder::Morton;
  uint32_t batch_points = kBatchPoints;
  // Large inputs are sorted and written on every core (same result, word for word); false
  // keeps everything on the calling thread (streaming workers, tests).
  bool parallel = true;
  BatchBuildStats* stats = nullptr;
  // Sets kTranslucentBit on points whose alpha is under 255: only for clouds whose alpha means
  // something (CloudAttributes::has_translucent; build_batches sets it from the cloud), since
  // points without RGB have alpha 0.
  bool mark_translucent = false;
};

// Sorts points (world space) along the curve and appends batches of at most `batch_points`
// consecutive points to `out`: boxes, quantized positions, colours and attribute words (empty
// `attributes`: class 1, single return). The order is that of (key, index), with the keys of
// points in over-full cells replaced by keys inside the cell's own box, recursively: so points
// that crowd into a few cells of the whole box (a far outlier stretching it) still batch into
// compact boxes.
void append_batches(BatchedCloud& out, std::span<const glm::dvec3> positions,
                    std::span<const uint32_t> colors, SpatialOrder order,
                    uint32_t batch_points = kBatchPoints,
                    std::span<const uint32_t> attributes = {});
void append_batches(BatchedCloud& out, std::span<const glm::dvec3> positions,
                    std::span<const uint32_t> colors, std::span<const uint32_t> attributes,
                    const BatchingOptions& options);

// The same from chunks (a loaded cloud, a decoded tile): positions are each chunk's origin plus
// its float offsets, colours and attribute words its vertices'.
void append_chunk_batches(BatchedCloud& out, std::span<const PointChunk> chunks,
                          const BatchingOptions& options = {});

// A loaded cloud, sorted and batched as a whole (its translucent points marked where the cloud
// has some).
BatchedCloud build_batches(const PointCloud& cloud, const BatchingOptions& options = {});

// The built-in scene of params.point_count points, generated in parallel pieces of consecutive
// indices (each spatially coherent: the scene is scanned line by line), each piece sorted and
// batched on its own and quantized while generating, so only ~20 bytes per point stay.
BatchedCloud generate_batched_scene(const io::SceneParams& params, SpatialOrder order,
                                    uint32_t batch_points = kBatchPoints, bool progress = false);

// ---- per-frame culling, the CPU twin of compute_raster_common.wgsl -------------------------
// Thresholds on the projected size (the larger side of the screen-space box, pixels).
struct CullSettings {
  uint32_t width = 0, height = 0;
  float min_batch_px = 0.0f;  // LOD: batches smaller than this on screen are skipped
  int force_bits = 0;         // 0: from the projected size; else 10, 20 or 30
};
struct BatchVisibility {
  bool visible = false;   // inside the frustum and not skipped
  bool lod_skip = false;  // in the frustum but below min_batch_px
  int bits = 0;           // precision for visible batches
  float size_px = 0.0f;   // projected size; +inf when the box reaches behind the near plane
};
// `offset` is batch.min - camera.position cast to float; view_proj the float rotation-only
// view-projection. Mirrors the shader's float arithmetic.
BatchVisibility classify_batch(const glm::mat4& view_proj, const glm::vec3& offset,
                               const glm::vec3& size, const CullSettings& settings);
int precision_bits(float size_px);

struct RasterCounters {
  uint32_t batches_processed = 0, batches_rendered = 0, batches_culled = 0, batches_lod_skipped = 0;
  uint64_t points_rendered = 0;
  uint32_t batches_by_bits[3] = {0, 0, 0};  // 10, 20, 30 bits
  uint64_t points_by_bits[3] = {0, 0, 0};
  // The 32-bit fallback's winner events (RasterKernel::fallback_events): how many the depth pass
  // appended, and whether they outgrew the list (the colour pass then ran).
  uint64_t events = 0;
  bool events_overflowed = false;
};
// What the GPU should count for this camera (a float view-projection like the renderer's).
RasterCounters reference_counters(const std::vector<Batch>& batches, const Camera& camera,
                                  const CullSettings& settings);
glm::mat4 raster_view_proj(const Camera& camera, uint32_t width, uint32_t height);

}  // namespace stipple::pc
