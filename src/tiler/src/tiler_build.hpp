#pragma once
// The state one tiling (or merge) shares between its phases, as plain data: the options, the
// inputs, the local frame and octree cube, the count grid and the chunks cut from it, the nodes
// written so far and the chunk roots waiting for the upper levels, the pool, the output
// directories and the profile. tiler.cpp sequences the phases (tiler_input, tiler_chunks,
// tiler_index, tiler_upper, tiler_content, tiler_tileset, tiler_parts), each a set of free
// functions taking this struct. Not part of the public API.
#include <atomic>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "stipple/core/progress.hpp"
#include "stipple/core/thread_pool.hpp"
#include "stipple/io/las.hpp"
#include "stipple/tiler/geo_frame.hpp"
#include "stipple/tiler/profile.hpp"
#include "stipple/tiler/tile_point.hpp"
#include "stipple/tiler/tiler.hpp"

namespace stipple::tiler::detail {

namespace fs = std::filesystem;

struct NodeKey {
  int level = 0;
  uint32_t x = 0, y = 0, z = 0;
  auto operator<=>(const NodeKey&) const = default;
  NodeKey child(int i) const {
    return {level + 1, 2 * x + (i & 1), 2 * y + ((i >> 1) & 1), 2 * z + ((i >> 2) & 1)};
  }
  NodeKey parent() const { return {level - 1, x / 2, y / 2, z / 2}; }
  std::string name() const { return fmt::format("{}-{}-{}-{}", level, x, y, z); }
};

struct NodeInfo {
  uint64_t points = 0;
  Box content;  // of the written content; empty when the tile has none
};

struct Input {
  std::string path;
  std::string crs;
  io::LasHeader header;
};

struct Chunk {
  NodeKey key;
  uint64_t count = 0;
  fs::path file;
  std::mutex mutex;
  bool resident = false;  // points at Build::resident[offset, offset + count), not in file
  uint64_t offset = 0;
  uint64_t expected = 0;            // points counted in its cells (out-of-core distribution)
  std::vector<TilePoint> pending;   // not resident: records not yet appended to `file`
  std::atomic<uint64_t> filled{0};  // resident, out of core: records placed so far
};

// Removes the partial output unless the run commits.
struct PartialDir {
  fs::path path;
  bool committed = false;
  ~PartialDir() {
    if (!committed && !path.empty()) {
      std::error_code ec;
      fs::remove_all(path, ec);
    }
  }
};

// The members are declared in the order they are torn down in (last first): the partial
// output goes before the pool and the points.
struct Build {
  explicit Build(const TileOptions& o) : opt(o) {}
  Build(const Build&) = delete;
  Build& operator=(const Build&) = delete;

  const TileOptions& opt;
  // Inputs and frame (tiler_input).
  std::vector<Input> inputs;
  uint64_t total_points = 0;  // of the part, once counted, in a split tiling
  ContentOptions content;
  LocalFrame frame;
  glm::dvec3 cube_min{0};
  double cube_size = 1, root_spacing = 1;
  // Count grid and budget (tiler_chunks).
  int count_level = 7;
  double count_cells = 128;  // 2^count_level cells an axis
  size_t batch_points = 1 << 20, chunk_points = 0;
  int max_level = 24;
  std::unique_ptr<ThreadPool> pool;
  fs::path dir, tmp;  // the partial output directory and its temporary files
  std::chrono::steady_clock::time_point phase_start = std::chrono::steady_clock::now();
  std::string phase_name;
  Profiler prof;

  // Chunks (tiler_chunks).
  size_t chunk_buffer_points = 0;  // a chunk file is appended to this many records at a time
  // In-memory mode (the records of every input fit the budget twice over): the reading pass
  // stages records in memory and the chunks stay resident; no temporary files for them.
  bool in_memory = false;
  std::unique_ptr<TilePoint[]> staged_mem;
  std::unique_ptr<TilePoint[]> resident;  // every chunk's points, chunk after chunk
  std::atomic<uint64_t> staged_fill{0};
  std::vector<std::unique_ptr<Chunk>> chunks;
  std::vector<int32_t> cell_chunk;  // chunk of every count cell, -1 where none

  // Nodes (tiler_index, tiler_upper, tiler_content).
  std::mutex lattice_mutex;
  LatticeStats lattice;
  std::mutex nodes_mutex;
  std::map<NodeKey, NodeInfo> nodes;
  std::map<NodeKey, fs::path> pending_roots;  // chunk roots waiting for the upper levels
  std::atomic<uint64_t> written{0};
  std::unique_ptr<Progress> index_progress;
  uint64_t indexed = 0;
  std::mutex progress_mutex;
  // Split tiling (tiler_parts): the part's level (0: the whole cube) and its shape.
  int part_level = 0;
  bool part_columns = false;  // N a power of 4: columns of (x, y) at part_level
  std::unique_ptr<PartialDir> partial;
};

// The counting grid's cell of a point: floor((p - min) / size * 2^L) clamped to the grid, per
// axis. Inline and without floor's call: every point passes here twice or three times. The
// expression is evaluated as it always was (division, not a multiplication by the inverse), so
// points on a cell boundary stay in their cell; truncation equals floor once negative values
// are clamped to 0 (NaN goes to 0, as the conversion gave before).
inline uint32_t cell_axis(const Build& b, double v, int k) {
  double g = (v - b.cube_min[k]) / b.cube_size * b.count_cells;
  g = g > 0.0 ? g : 0.0;
  g = g < b.count_cells - 1 ? g : b.count_cells - 1;
  return uint32_t(g);
}
inline uint32_t cell_of(const Build& b, double x, double y, double z) {
  return (cell_axis(b, z, 2) << (2 * b.count_level)) | (cell_axis(b, y, 1) << b.count_level) |
         cell_axis(b, x, 0);
}
inline uint32_t cell_of(const Build& b, const glm::dvec3& p) {
  return cell_of(b, p.x, p.y, p.z);
}
inline uint32_t cell_of(const Build& b, const TilePoint& p) {
  return cell_of(b, p.x, p.y, p.z);
}

// Split tiling: whether a count cell lies in this run's part. Inline: the counting pass asks it
// of every point.
inline bool cell_in_part(const Build& b, uint32_t cell) {
  if (b.part_level == 0) return true;
  const uint32_t mask = (1u << b.count_level) - 1, shift = uint32_t(b.count_level - b.part_level);
  const uint32_t x = (cell & mask) >> shift, y = ((cell >> b.count_level) & mask) >> shift;
  const uint32_t z = (cell >> (2 * b.count_level)) >> shift, n = 1u << b.part_level;
  const uint32_t index = b.part_columns ? x + y * n : x + (y + z * n) * n;
  return index == b.opt.subset_index;
}

inline double node_size(const Build& b, int level) {
  return b.cube_size / double(uint64_t(1) << level);
}
inline glm::dvec3 node_min(const Build& b, const NodeKey& k) {
  return b.cube_min + glm::dvec3(k.x, k.y, k.z) * node_size(b, k.level);
}
inline double spacing(const Build& b, int level) {
  return b.root_spacing / double(uint64_t(1) << level);
}

inline void report(const Build& b, const char* phase, uint64_t done, uint64_t total) {
  if (b.opt.progress) b.opt.progress(phase, done, total);
}

}  // namespace stipple::tiler::detail
