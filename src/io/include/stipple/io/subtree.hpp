#pragma once
// Subtree files of 3D Tiles implicit tiling: availability of tiles, contents and child subtrees,
// each a constant or a bitstream (bit i of byte i/8, least significant first) indexed by the
// tile's Morton index within its level, levels concatenated.
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "stipple/io/glb_points.hpp"  // BufferResolver

namespace stipple::io {

struct Availability {
  bool constant = true;
  bool value = false;         // when constant
  std::vector<uint8_t> bits;  // when a bitstream
  uint64_t bit_count = 0;
  bool get(uint64_t index) const {
    if (constant) return value;
    return index < bit_count && (bits[index >> 3] >> (index & 7)) & 1;
  }
};

struct Subtree {
  Availability tiles;
  std::vector<Availability> contents;  // one per content of the tile (1.1 allows several)
  Availability child_subtrees;
};

// Tiles in one subtree of `levels` levels of a tree with `branching` (4 or 8) children.
uint64_t subtree_tile_count(int branching, int levels);
// Index of a tile in a subtree's tile/content availability: (N^level - 1)/(N - 1) + morton.
uint64_t availability_index(int branching, int level, uint64_t morton);
uint64_t morton_index(uint32_t x, uint32_t y, uint32_t z, int branching);

// Parses a binary (.subtree) or JSON subtree; external buffers come through `resolver`.
// Throws stipple::Error.
Subtree decode_subtree(std::span<const uint8_t> data, const std::string& name, int branching,
                       int levels, const BufferResolver& resolver = nullptr);

}  // namespace stipple::io
