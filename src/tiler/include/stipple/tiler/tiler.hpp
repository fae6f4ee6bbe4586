#pragma once
// LAS/LAZ -> 3D Tiles, out of core (issue 7). See tiler.cpp for the pipeline.
#include <cstdint>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "stipple/tiler/profile.hpp"

namespace stipple::tiler {

enum class Format { Glb, Pnts };

struct TileOptions {
  std::vector<std::string> inputs;
  std::string output;
  Format format = Format::Glb;
  std::string crs;     // e.g. "EPSG:2992": overrides every input's own CRS
  double spacing = 0;  // root spacing in metres; 0: cube edge / 128 (as Potree)
  uint64_t max_memory = 2ull << 30;
  unsigned threads = 0;            // 0: every core
  bool force = false;              // replace an existing output directory
  size_t max_node_points = 60000;  // tile cap: larger nodes are split / subsampled further
  // none, meshopt (glb: EXT_meshopt_compression) or draco (pnts: 3DTILES_draco_point_compression)
  std::string compression = "none";
  // 3D Tiles 1.1 implicit tiling: an octree whose availability is in subtree files of
  // `subtree_levels` levels, instead of every tile listed in tileset.json.
  bool implicit = false;
  int subtree_levels = 6;
  // Split tiling (Entwine's subset + merge): tile only part `subset_index` of `subset_count`
  // spatial parts of the root cube (0: the whole). `subset_count` is a power of 8 (the octree
  // nodes of level log8 N, x fastest, then y, then z) or else of 4 (the columns of level log4 N:
  // every z of one x, y). Each part writes the complete subtrees under its nodes, but for the
  // nodes themselves (the part roots, whose final content depends on the parts around them),
  // kept as raw points for merge_parts; `output` is then the part's directory, not a tileset.
  uint32_t subset_index = 0, subset_count = 0;
  // Called as the work advances with the phase ("reading", "indexing", ...), the points done
  // and the phase's total; from worker threads, one call at a time.
  std::function<void(const std::string& phase, uint64_t done, uint64_t total)> progress;
  // Sample every millisecond how many threads run (PhaseProfile::one_thread); the phases' times,
  // CPU and I/O are recorded either way.
  bool sample_threads = false;
};

struct TileStats {
  uint64_t points = 0;  // points read = points written
  uint64_t tiles = 0;
  int depth = 0;      // deepest level
  size_t chunks = 0;  // out-of-core chunks indexed independently
  double root_spacing = 0;
  double seconds = 0;
  unsigned threads = 0;              // worker threads used
  std::vector<PhaseProfile> phases;  // in order; their wall times add up to `seconds`
  std::vector<StepProfile> steps;    // indexed by Step
};

// The profile as a table (one row a phase, then one a step), and the stats as JSON.
std::string profile_table(const TileStats& stats);
std::string stats_json(const TileStats& stats);

TileStats build_tileset(const TileOptions& options);

// "I/N" (--subset) -> index, count; throws stipple::Error unless 0 <= I < N and N is a power of 4
// or 8 (N >= 4).
std::pair<uint32_t, uint32_t> parse_subset(const std::string& text);

struct MergeOptions {
  std::vector<std::string> parts;  // the output directories of every subset I/N of one split
  std::string output;
  bool force = false;
  unsigned threads = 0;
  uint64_t max_memory = 2ull << 30;
  std::function<void(const std::string& phase, uint64_t done, uint64_t total)> progress;
};

// Builds the levels above the parts (each parent subsampled from its children's points at its
// spacing, as build_tileset does above its chunks) and one tileset.json over the parts' tiles,
// which are linked (or copied) into `output`; the parts are left as they were, so a merge can be
// run again. The result holds exactly the points of build_tileset over the same inputs, with the
// same spacing rules. Throws stipple::Error naming the part for a missing, repeated or
// mismatched part.
TileStats merge_parts(const MergeOptions& options);

}  // namespace stipple::tiler
