#pragma once
// Subtree files of 3D Tiles 1.1 implicit tiling, binary (.subtree): tile, content and
// child-subtree availability, each a constant where every bit is equal, else a bitstream (bit i
// of byte i/8, least significant first) in the binary body, 8-byte aligned.
#include <cstdint>
#include <vector>

namespace stipple::tiler {

// Bits indexed as io::availability_index (tiles, content) and io::morton_index (child subtrees).
std::vector<uint8_t> write_subtree(const std::vector<bool>& tiles, const std::vector<bool>& content,
                                   const std::vector<bool>& child_subtrees);

}  // namespace stipple::tiler
