#pragma once
// Pointlets and the pointlet cache (seed 002, section III-A): the input points sorted along a
// space-filling curve (Hilbert by default) and cut into fixed-size groups of k = 2^floor(log2(n /
// m)) points (eq. 1), each with its axis-aligned box; inside a pointlet the points are shuffled,
// so that any prefix of it is a uniform subsample (the LoD reads prefixes). The sort is external:
// runs of at most the memory budget are sorted on every core and written to disk, then merged,
// so a file of any size is organised in bounded memory. The result is a cache file beside the
// input (or in a folder of one's choosing), reused while the sources are unchanged.
//
// Cache layout (version 1, little endian; docs/pointlet-cache.md):
//   header (kPointletHeaderBytes): magic "STPLTCHE", version, sizes, counts, k, order,
//     quantisation step, bounds, attributes, the sources' sizes and mtimes, the offsets of the
//     table and the points, CRC-32s of the table and of the header itself
//   points: per pointlet, `count` PointletRecords (20 bytes), contiguous, in table order
//   table: per pointlet, PointletEntry (box, first point, count, CRC-32 of its records)
#include <array>
#include <atomic>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "stipple/math/aabb.hpp"
#include "stipple/pointcloud/batches.hpp"
#include "stipple/pointcloud/point_cloud.hpp"

namespace stipple::pc {

inline constexpr uint32_t kPointletCacheVersion = 1;
inline constexpr uint64_t kPointletHeaderBytes = 4096;  // room for the sources' names
inline constexpr uint64_t kDefaultPointlets = 100'000;  // m of eq. 1

// k = 2^floor(log2(n / m)) (eq. 1), at least 1.
uint64_t pointlet_size(uint64_t points, uint64_t pointlets);

// One point as stored: its position in steps of the cache's quantisation (the source's LAS
// scale) from its pointlet's box minimum, and its attributes packed as the colour modes read
// them (PointChunk::Vertex: 8-bit RGB; intensity, class and returns in one word).
struct PointletRecord {
  uint32_t q[3];
  uint32_t rgba;
  uint32_t attributes;
};
static_assert(sizeof(PointletRecord) == 20);

struct PointletEntry {
  double min[3], max[3];  // the box of the pointlet's points, source frame (Z up)
  uint64_t first = 0;     // index of its first point in the cache
  uint32_t count = 0;
  uint32_t crc = 0;  // CRC-32 of its records
};
static_assert(sizeof(PointletEntry) == 64);

// What a cache was made from: reused only while every source has the same size and mtime.
struct PointletSource {
  std::string path;  // as given (absolute)
  uint64_t size = 0;
  int64_t mtime_ns = 0;
  uint64_t points = 0;
};

struct PointletCacheInfo {
  uint32_t version = kPointletCacheVersion;
  uint64_t point_count = 0, pointlet_count = 0;
  uint64_t pointlet_points = 1;                      // k
  uint64_t requested_pointlets = kDefaultPointlets;  // m
  SpatialOrder order = SpatialOrder::Hilbert;
  glm::dvec3 scale{0.001};  // quantisation step per axis (source units)
  Aabb source_bounds;       // of every point, source frame (Z up)
  CloudAttributes attributes;
  bool geographic = false;     // positions are metres in a local ENU frame at enu_origin
  glm::dvec3 enu_origin{0.0};  // lon, lat, 0 of that frame
  std::vector<PointletSource> sources;
  uint64_t points_offset = kPointletHeaderBytes, table_offset = 0, file_size = 0;
};

// A build's progress, counted by the build and read by other threads (the viewer's panel while
// the cache builds in the background): phase 1 reads and sorts the input, phase 2 merges and
// writes the pointlets; each counts `done` of `total` points.
struct PointletBuildProgress {
  std::atomic<uint32_t> phase{0};  // 0: not started, 1: read and sort, 2: write, 3: done
  std::atomic<uint64_t> done{0}, total{0};
  // Set by the reader to end the build early (the viewer closed): it throws stipple::Error and
  // leaves no cache behind.
  std::atomic<bool> cancel{false};
  // The whole build's fraction, 0..1 (the two phases weigh alike).
  double fraction() const;
};

struct PointletBuildOptions {
  uint64_t pointlets = kDefaultPointlets;  // m
  SpatialOrder order = SpatialOrder::Hilbert;
  // Bytes of points sorted in memory at once (runs); larger inputs are sorted in several runs
  // on disk and merged.
  uint64_t memory_budget = uint64_t(1) << 30;
  unsigned threads = 0;  // 0: every core
  bool progress = true;
  std::filesystem::path temp_dir;                 // runs; empty: beside the cache
  std::shared_ptr<PointletBuildProgress> report;  // where set, the build counts its progress
};

// The build's phases, wall seconds each (every phase runs on every core): read (the inputs
// decoded and their curve keys), sort (radix sorts of the runs and of the merge's windows),
// merge (sorted runs read back from disk), encode (shuffles, boxes, CRCs) and write (runs and
// the cache).
struct PointletBuildStats {
  uint64_t points = 0, pointlets = 0, pointlet_points = 0, runs = 0;
  // write_seconds: the writes' own time, which overlaps the reads (they run in the background;
  // for the runs it includes their compression, done on the write threads); write_wait_seconds:
  // how long the build waited for them.
  double read_seconds = 0, sort_seconds = 0, merge_seconds = 0, encode_seconds = 0,
         write_seconds = 0, write_wait_seconds = 0, seconds = 0;
  uint64_t peak_run_bytes = 0;  // the largest run held in memory
  // The runs on disk: their records' bytes, and their compressed bytes (0 without runs; on disk
  // each block takes whole pages); of merge_seconds, the windows' reading back and
  // decompressing of the runs (a dense prefix's merge reads its own).
  uint64_t run_bytes = 0, run_disk_bytes = 0;
  double run_read_seconds = 0;
};

// One line: "cache build: N M points/s; read a s, sort b s, merge c s (runs read back r s),
// encode d s, write e s (beside the reads; f s waited for); R runs (X GB of records, Y GB
// compressed)" (the --stats of `stipple pointlets` and of the virtualized render).
std::string describe_build_phases(const PointletBuildStats& stats);

// Builds the cache of `sources` (LAS/LAZ/COPC, read whole) at `cache_path`, atomically: the
// file appears complete or not at all. Throws stipple::Error naming the file at fault.
PointletBuildStats build_pointlet_cache(const std::vector<std::filesystem::path>& sources,
                                        const std::filesystem::path& cache_path,
                                        const PointletBuildOptions& options = {});

// An open cache: header and table validated, points read on demand with positional reads (any
// thread). Every offset and count is checked against the file before use; a broken cache gives
// stipple::Error naming the file and what is wrong.
class PointletCache {
 public:
  static PointletCache open(const std::filesystem::path& path);
  // The same from bytes in memory (tests, fuzzing).
  static PointletCache from_memory(std::vector<uint8_t> bytes, std::string name = "<memory>");
  PointletCache(PointletCache&&) noexcept;
  PointletCache& operator=(PointletCache&&) noexcept;
  ~PointletCache();

  const std::string& name() const { return name_; }
  const PointletCacheInfo& info() const { return info_; }
  const std::vector<PointletEntry>& pointlets() const { return table_; }
  // Records [first, first + count) of pointlet `index`, appended to `out`.
  void read(uint32_t index, uint32_t first, uint32_t count, std::vector<PointletRecord>& out) const;
  // Reads a whole pointlet and checks its CRC; throws when it does not match.
  std::vector<PointletRecord> read_verified(uint32_t index) const;
  // A record's position in the source frame.
  glm::dvec3 position(const PointletEntry& pointlet, const PointletRecord& record) const;
  // Whether it was built from these sources as they are now (sizes and mtimes), with this m
  // and order.
  bool matches(const std::vector<std::filesystem::path>& sources,
               const PointletBuildOptions& options) const;

 private:
  PointletCache() = default;
  struct Storage;
  std::unique_ptr<Storage> storage_;
  std::string name_;
  PointletCacheInfo info_;
  std::vector<PointletEntry> table_;
  void load();
};

// Where the cache of `sources` lives: `cache_dir` when given, else beside the first source when
// that folder is writable, else $XDG_CACHE_HOME/stipple (~/.cache/stipple). The name joins the
// first source's name with a hash of every source's absolute path, m and the order.
std::filesystem::path pointlet_cache_path(const std::vector<std::filesystem::path>& sources,
                                          const std::filesystem::path& cache_dir,
                                          const PointletBuildOptions& options);

// Opens the cache of `sources`, building it first when it is missing, made from other sources
// (or older versions of them) or unreadable; `built` says which happened.
PointletCache open_pointlet_cache(const std::vector<std::filesystem::path>& sources,
                                  const std::filesystem::path& cache_dir,
                                  const PointletBuildOptions& options, bool* built = nullptr,
                                  PointletBuildStats* stats = nullptr);

// Whether open_pointlet_cache would reuse the cache as it is (it exists, opens, and was made
// from these sources as they are now), without building anything.
bool pointlet_cache_current(const std::vector<std::filesystem::path>& sources,
                            const std::filesystem::path& cache_dir,
                            const PointletBuildOptions& options);

// A pointlet's box in the engine's world frame (Y up; the table holds the source frame, Z up).
Aabb pointlet_world_box(const PointletEntry& pointlet);

// Table I of seed 002: how compact the pointlets are.
struct PointletMetrics {
  double max_extent = 0, mean_extent = 0, stddev_extent = 0;  // largest side of each box
  double mean_squareness = 0;  // 1 - shorter / longer horizontal side (0: a square footprint)
};
PointletMetrics pointlet_metrics(const std::vector<PointletEntry>& pointlets);

}  // namespace stipple::pc
