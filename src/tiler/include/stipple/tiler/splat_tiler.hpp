#pragma once
// Gaussian splats -> 3D Tiles 1.1 (issue 46): `stipple tile scene.ply|.spz|.splat|... -o DIR`
// writes a tileset whose contents are glb with KHR_gaussian_splatting (splat_glb.hpp), with
// level of detail: an octree over the splats' bounding cube whose leaves hold the input splats
// exactly (each splat in one leaf, at most `max_leaf_splats` a leaf) and whose inner nodes hold
// moment-matched merges of their children's splats (splat_merge.hpp), about 1/merge_ratio of
// them (merge_ratio), with REPLACE refinement and the merge's cell size as geometric error.
//
// Out of core: an INRIA PLY is read in blocks (its records are fixed-size), other inputs are
// decoded whole (their readers decode whole files); the splats are appended as records to a
// staging file and released; the staging file is counted on a
// grid and cut into chunks (octree nodes) of a size the memory budget allows, distributed to
// one file a chunk, and every chunk's subtree is built on its own, chunks in parallel; the
// chunk roots' merged splats go to files, from which the levels above them are built.
//
// Frames: the splats stay in their set's frame, treated as glTF's Y-up frame; the set's transform
// (the half turn of the PLY family, a glb's node matrix) becomes the root tile's transform (in
// the Z-up tile frame), so neither positions nor SH coefficients are resampled. Inputs of one
// run must share that transform and their SH degree.
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "stipple/tiler/splat_glb.hpp"

namespace stipple::tiler {

struct SplatTileOptions {
  std::vector<std::string> inputs;
  std::string output;
  SplatCompression compression = SplatCompression::Spz;
  size_t max_leaf_splats = 65536;
  // An inner node holds about 1/merge_ratio of its children's splats: the levels above the leaves
  // add about 1/(merge_ratio - 1) to the output (the size goal is 1.1x the SPZ of the input).
  double merge_ratio = 16;
  uint64_t max_memory = 2ull << 30;
  unsigned threads = 0;  // 0: every core
  bool force = false;
  // Test hook: at most this many splats a chunk (0: from max_memory).
  size_t chunk_splats = 0;
};

struct SplatTileStats {
  uint64_t splats = 0;         // read = held by the leaves
  uint64_t merged_splats = 0;  // held by the inner nodes
  uint64_t tiles = 0, leaves = 0;
  uint64_t bytes = 0;  // of the glb contents
  int depth = 0;
  size_t chunks = 0;
  int sh_degree = 0;
  double seconds = 0;
};

SplatTileStats build_splat_tileset(const SplatTileOptions& options);

}  // namespace stipple::tiler
