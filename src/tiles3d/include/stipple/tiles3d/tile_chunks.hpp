#pragma once
// A tile's decoded content converted for rendering: chunks in the engine's world frame (double
// origins, float offsets). The streamer's workers make them right after decoding
// (StreamerOptions::prepare), so the thread that drives the engine never touches points.
#include <cstdint>
#include <memory>
#include <vector>

#include <glm/mat4x4.hpp>

#include "stipple/io/pnts.hpp"
#include "stipple/pointcloud/batches.hpp"
#include "stipple/pointcloud/compute_raster.hpp"
#include "stipple/pointcloud/point_cloud.hpp"

namespace stipple::tiles3d {

// One tile's content as render-ready chunks (world space, double origins). Never modified once
// built; the render world holds it while the tile's GPU buffers live.
struct TileChunks {
  uint32_t tile = 0;
  std::vector<pc::PointChunk> chunks;
  uint64_t points = 0;
  uint64_t transparent_points = 0;  // left out: alpha 0 (io::PointContent::alpha)
  pc::CloudAttributes attributes;   // which attributes the tile has
  // Up to 128 intensities strided evenly through the tile: the drawn tiles' samples, weighted by
  // their point counts, give the intensity ramp's percentiles.
  std::vector<uint16_t> intensity_sample;
  // The tile as LOD batches of the compute rasterizer (seed 001, section 3.5), sorted and
  // quantized on the worker; null unless asked for.
  std::shared_ptr<const pc::BatchedCloud> batches;
  uint64_t memory_bytes() const;
};

// A tile's decoded contents as chunks in the engine's world frame (on a streamer worker), and
// with `batches` as LOD batches too (Morton order; the rasterizer colours them per frame).
std::shared_ptr<const TileChunks> make_tile_chunks(uint32_t tile, const glm::dmat4& tile_transform,
                                                   const glm::dmat4& world_from_tileset,
                                                   const std::vector<io::PointContent>& contents,
                                                   bool batches = false);

}  // namespace stipple::tiles3d
