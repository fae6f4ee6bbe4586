#include "stipple/tiles3d/tile_chunks.hpp"

#include <algorithm>

#include "stipple/tiles3d/render_load.hpp"

namespace stipple::tiles3d {

uint64_t TileChunks::memory_bytes() const {
  uint64_t bytes = sizeof(TileChunks);
  for (const auto& c : chunks)
    bytes += sizeof(pc::PointChunk) + c.vertices.capacity() * sizeof(pc::PointChunk::Vertex);
  if (batches)
    bytes += sizeof(pc::BatchedCloud) + batches->point_count() * pc::kRasterPointBytes +
             batches->batches.size() * sizeof(pc::Batch);
  return bytes;
}

std::shared_ptr<const TileChunks> make_tile_chunks(uint32_t tile, const glm::dmat4& tile_transform,
                                                   const glm::dmat4& world_from_tileset,
                                                   const std::vector<io::PointContent>& contents,
                                                   bool batches) {
  pc::PointCloud cloud;
  uint64_t transparent = 0;
  for (const auto& c : contents)
    transparent += append_content(cloud, c, tile_transform, world_from_tileset);
  pc::finish_cloud(cloud);  // per-chunk spacing (CLOD, adaptive sizes)
  auto out = std::make_shared<TileChunks>();
  out->tile = tile;
  out->transparent_points = transparent;
  out->points = cloud.point_count;
  out->attributes = cloud.attributes;
  out->chunks = std::move(cloud.chunks);
  if (cloud.attributes.has_intensity && cloud.point_count > 0) {
    const uint64_t stride = std::max<uint64_t>(1, cloud.point_count / 128);
    uint64_t i = 0;
    for (const auto& chunk : out->chunks)
      for (const auto& v : chunk.vertices)
        if (i++ % stride == 0) out->intensity_sample.push_back(uint16_t(v.attributes & 0xffffu));
  }
  if (batches) {
    // On this worker, alone: the workers already run one tile each.
    auto b = std::make_shared<pc::BatchedCloud>();
    pc::BatchingOptions options;
    options.parallel = false;
    options.mark_translucent = cloud.attributes.has_translucent;
    pc::append_chunk_batches(*b, out->chunks, options);
    out->batches = std::move(b);
  }
  return out;
}

}  // namespace stipple::tiles3d
