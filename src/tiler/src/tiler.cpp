// The tiler pipeline (Potree 2 / Entwine style, written for stipple):
//  1. headers: source CRS of each input -> ECEF (PROJ), one local ENU frame for the tileset,
//     the octree cube from the header boxes (densely sampled through the transform, padded);
//  2. counting pass: every point is transformed and counted in a grid at level Lc (<= 128^3);
//  3. chunking: the count pyramid is cut top-down into the largest octree nodes holding at
//     most `chunk_points` (sized from --max-memory and the thread count);
//  4. distribution pass: points are transformed again and appended to one temporary file per
//     chunk (raw TilePoint records);
//  5. indexing: chunks in parallel on the pool; each builds its subtree top-down: a node takes a
//     grid subsample at its level's spacing, the rest go to its 8 children, a node of at most
//     `max_node_points` keeps everything (leaf). Every point lands in exactly one node;
//  6. upper levels: from the deepest chunk roots up, a parent subsamples the union of its
//     children's points at its spacing; the selected points move up (additive refinement);
//  7. tileset.json, then DIR.partial-XXXXXX is renamed to DIR.
// Spacing halves per level; geometricError = spacing of the tile's level (factor 1: the point
// spacing the tile shows, which is what a client hides by not refining; CesiumJS's point
// attenuation reads it the same way).
#include "stipple/tiler/tiler.hpp"

#include <fcntl.h>
#include <stdlib.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <deque>
#include <filesystem>
#include <fstream>
#include <functional>
#include <future>
#include <map>
#include <mutex>
#include <semaphore>
#include <set>
#include <utility>

#include <nlohmann/json.hpp>

#include "stipple/core/error.hpp"
#include "stipple/core/log.hpp"
#include "stipple/core/progress.hpp"
#include "stipple/core/thread_pool.hpp"
#include "stipple/io/las.hpp"
#include "stipple/io/subtree.hpp"
#include "stipple/tiler/geo_frame.hpp"
#include "stipple/tiler/glb_writer.hpp"
#include "stipple/tiler/pnts_writer.hpp"
#include "stipple/tiler/sampling.hpp"
#include "stipple/tiler/subtree_writer.hpp"

namespace stipple::tiler {

namespace fs = std::filesystem;

namespace {

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

// One EcefTransform per thread and CRS (PROJ objects are not thread-safe).
const EcefTransform& thread_transform(const std::string& crs) {
  thread_local std::map<std::string, std::unique_ptr<EcefTransform>> cache;
  auto& t = cache[crs];
  if (!t) t = std::make_unique<EcefTransform>(crs);
  return *t;
}

// Closes a file descriptor when the scope ends, error paths included.
struct FdCloser {
  int fd = -1;
  ~FdCloser() {
    if (fd >= 0) ::close(fd);
  }
};

void write_all(int fd, const fs::path& path, const void* data, size_t size) {
  const char* p = static_cast<const char*>(data);
  while (size > 0) {
    ssize_t w = ::write(fd, p, size);
    if (w <= 0) fail("{}: write failed ({})", path.string(), std::strerror(errno));
    p += w, size -= size_t(w);
  }
}

// Writes `size` bytes to `path`, truncating (O_TRUNC) or appending (O_APPEND); a failed close
// is a failed write.
void put_file(const fs::path& path, int mode, const void* data, size_t size) {
  FdCloser file{::open(path.c_str(), O_WRONLY | O_CREAT | mode, 0644)};
  if (file.fd < 0) fail("{}: cannot open ({})", path.string(), std::strerror(errno));
  write_all(file.fd, path, data, size);
  if (::close(std::exchange(file.fd, -1)) != 0)
    fail("{}: write failed ({})", path.string(), std::strerror(errno));
}

void write_file(const fs::path& path, const void* data, size_t size) {
  put_file(path, O_TRUNC, data, size);
}

void append_file(const fs::path& path, const void* data, size_t size) {
  put_file(path, O_APPEND, data, size);
}

void read_points(const fs::path& path, std::vector<TilePoint>& pts) {
  pts.clear();
  std::error_code ec;
  uint64_t size = fs::file_size(path, ec);
  if (ec) return;
  pts.resize(size / sizeof(TilePoint));
  std::ifstream in(path, std::ios::binary);
  in.read(reinterpret_cast<char*>(pts.data()), std::streamsize(pts.size() * sizeof(TilePoint)));
  if (!in) fail("{}: cannot read temporary points", path.string());
}

std::vector<TilePoint> read_points(const fs::path& path) {
  std::vector<TilePoint> pts;
  read_points(path, pts);
  return pts;
}

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

class Tiler {
 public:
  explicit Tiler(const TileOptions& o) : opt_(o) {}
  TileStats run();
  TileStats merge(const std::vector<nlohmann::json>& parts, const std::vector<fs::path>& dirs);

 private:
  void open_inputs();
  void make_frame_and_cube();
  template <typename Process>
  void read_pass(const char* label, Process process, bool positions_only = false);
  void to_local(const Input& in, io::PointBatch& batch, std::vector<glm::dvec3>& out);
  void make_records(const Input& in, io::PointBatch& batch, TilePoint* out);
  void append_to_chunks(const TilePoint* recs, size_t n);
  void flush_chunk_buffers();
  void choose_resident_chunks(const std::vector<uint32_t>& counts);
  void distribute(const fs::path& staged, uint64_t count);
  void distribute_in_memory(uint64_t count);
  // The counting grid's cell of a point: floor((p - min) / size * 2^L) clamped to the grid, per
  // axis. Inline and without floor's call: every point passes here twice or three times. The
  // expression is evaluated as it always was (division, not a multiplication by the inverse), so
  // points on a cell boundary stay in their cell; truncation equals floor once negative values
  // are clamped to 0 (NaN goes to 0, as the conversion gave before).
  uint32_t cell_axis(double v, int k) const {
    double g = (v - cube_min_[k]) / cube_size_ * count_cells_;
    g = g > 0.0 ? g : 0.0;
    g = g < count_cells_ - 1 ? g : count_cells_ - 1;
    return uint32_t(g);
  }
  uint32_t cell_of(double x, double y, double z) const {
    return (cell_axis(z, 2) << (2 * count_level_)) | (cell_axis(y, 1) << count_level_) |
           cell_axis(x, 0);
  }
  uint32_t cell_of(const glm::dvec3& p) const { return cell_of(p.x, p.y, p.z); }
  uint32_t cell_of(const TilePoint& p) const { return cell_of(p.x, p.y, p.z); }
  // Ends the phase under way (logging its time) and starts `next` (none: the run is over).
  void phase(const char* next) {
    auto now = std::chrono::steady_clock::now();
    if (!phase_name_.empty())
      STIPPLE_INFO("tile: phase {:<30} {:8.3f} s", phase_name_,
                   std::chrono::duration<double>(now - phase_start_).count());
    phase_start_ = now;
    phase_name_ = next ? next : "";
    if (next)
      prof_.phase(next);
    else
      prof_.finish();
  }
  void plan_chunks(const std::vector<uint32_t>& counts);
  void split_oversized_chunks();
  void index_chunk(size_t chunk);
  void index_node(const NodeKey& key, std::span<TilePoint> pts, bool chunk_root);
  void build_upper_levels();
  void write_content(const NodeKey& key, std::span<const TilePoint> pts);
  void record(const NodeKey& key, std::span<const TilePoint> pts);
  void write_tileset();
  nlohmann::json write_implicit();
  void write_part();
  fs::path begin_output(const std::string& output);
  TileStats commit(const fs::path& out, std::chrono::steady_clock::time_point start);
  // Split tiling: whether a count cell lies in this run's part, and drops the records that do
  // not (in place); returns how many are kept.
  bool cell_in_part(uint32_t cell) const;
  size_t keep_in_part(TilePoint* recs, size_t n) const;
  void report(const char* phase, uint64_t done, uint64_t total) {
    if (opt_.progress) opt_.progress(phase, done, total);
  }
  glm::dvec3 node_min(const NodeKey& k) const {
    return cube_min_ + glm::dvec3(k.x, k.y, k.z) * node_size(k.level);
  }
  double node_size(int level) const { return cube_size_ / double(uint64_t(1) << level); }
  double spacing(int level) const { return root_spacing_ / double(uint64_t(1) << level); }

  const TileOptions& opt_;
  std::vector<Input> inputs_;
  uint64_t total_points_ = 0;
  ContentOptions content_;
  LocalFrame frame_;
  glm::dvec3 cube_min_{0};
  double cube_size_ = 1, root_spacing_ = 1;
  int count_level_ = 7;
  double count_cells_ = 128;  // 2^count_level_ cells an axis
  size_t batch_points_ = 1 << 20, chunk_points_ = 0;
  int max_level_ = 24;
  std::unique_ptr<ThreadPool> pool_;
  fs::path dir_, tmp_;
  std::chrono::steady_clock::time_point phase_start_ = std::chrono::steady_clock::now();
  std::string phase_name_;
  Profiler prof_;

  struct Chunk {
    NodeKey key;
    uint64_t count = 0;
    fs::path file;
    std::mutex mutex;
    bool resident = false;  // points at resident_[offset, offset + count), not in file
    uint64_t offset = 0;
    uint64_t expected = 0;            // points counted in its cells (out-of-core distribution)
    std::vector<TilePoint> pending;   // not resident: records not yet appended to `file`
    std::atomic<uint64_t> filled{0};  // resident, out of core: records placed so far
  };
  size_t chunk_buffer_points_ = 0;  // a chunk file is appended to this many records at a time
  // In-memory mode (the records of every input fit the budget twice over): the reading pass
  // stages records in memory and the chunks stay resident; no temporary files for them.
  bool in_memory_ = false;
  std::unique_ptr<TilePoint[]> staged_mem_;
  std::unique_ptr<TilePoint[]> resident_;  // every chunk's points, chunk after chunk
  std::atomic<uint64_t> staged_fill_{0};
  std::vector<std::unique_ptr<Chunk>> chunks_;
  std::vector<int32_t> cell_chunk_;

  std::mutex lattice_mutex_;
  LatticeStats lattice_;
  std::mutex nodes_mutex_;
  std::map<NodeKey, NodeInfo> nodes_;
  std::map<NodeKey, fs::path> pending_roots_;  // chunk roots waiting for the upper levels
  std::atomic<uint64_t> written_{0};
  std::unique_ptr<Progress> index_progress_;
  uint64_t indexed_ = 0;
  std::mutex progress_mutex_;
  // Split tiling: the part's level (0: the whole cube) and its shape.
  int part_level_ = 0;
  bool part_columns_ = false;  // N a power of 4: columns of (x, y) at part_level_
  std::unique_ptr<PartialDir> partial_;
};

// Adds one to counts[cell] for each point with few atomics: a thread's repeats of a cell (a
// LiDAR file comes in scan order, so points near in the file share cells) are summed in a small
// direct-mapped table and added once, when the slot is taken by another cell or at the end of
// the batch. At 16 threads the shared counters' cache lines moving between cores made the count
// step cost 2.6x the CPU of one thread (4.1 s against 1.55 s on 100M points, H200 host).
class CellCounter {
 public:
  explicit CellCounter(std::vector<std::atomic<uint32_t>>& counts) : counts_(counts) {}
  CellCounter(const CellCounter&) = delete;
  CellCounter& operator=(const CellCounter&) = delete;
  ~CellCounter() {
    for (const Slot& s : slots_)
      if (s.n) counts_[s.cell].fetch_add(s.n, std::memory_order_relaxed);
  }
  void add(uint32_t cell) {
    Slot& s = slots_[(cell * 0x9E3779B1u) >> (32 - kSlotBits)];
    if (s.cell == cell && s.n) {
      ++s.n;
      return;
    }
    if (s.n) counts_[s.cell].fetch_add(s.n, std::memory_order_relaxed);
    s.cell = cell, s.n = 1;
  }

 private:
  static constexpr int kSlotBits = 10;
  struct Slot {
    uint32_t cell = 0, n = 0;
  };
  std::array<Slot, size_t(1) << kSlotBits> slots_{};
  std::vector<std::atomic<uint32_t>>& counts_;
};

bool Tiler::cell_in_part(uint32_t cell) const {
  if (part_level_ == 0) return true;
  const uint32_t mask = (1u << count_level_) - 1, shift = uint32_t(count_level_ - part_level_);
  const uint32_t x = (cell & mask) >> shift, y = ((cell >> count_level_) & mask) >> shift;
  const uint32_t z = (cell >> (2 * count_level_)) >> shift, n = 1u << part_level_;
  const uint32_t index = part_columns_ ? x + y * n : x + (y + z * n) * n;
  return index == opt_.subset_index;
}

size_t Tiler::keep_in_part(TilePoint* recs, size_t n) const {
  if (part_level_ == 0) return n;
  size_t kept = 0;
  for (size_t i = 0; i < n; ++i)
    if (cell_in_part(cell_of(recs[i]))) recs[kept++] = recs[i];
  return kept;
}

void Tiler::open_inputs() {
  if (opt_.inputs.empty()) fail("no input files");
  for (const std::string& path : opt_.inputs) {
    Input in;
    in.path = path;
    in.header = io::read_las_header(path);
    if (const std::string problem = io::geographic_bounds_problem(in.header);
        !problem.empty() && opt_.crs.empty())
      fail("{}", problem);
    // The reader detects 8-bit colour stored in 16-bit fields from the first points
    // (read_las_header cannot): make_records scales by it.
    if (in.header.has_rgb) in.header.rgb_bits = io::LasReader(path).header().rgb_bits;
    in.crs = source_crs_definition(in.header, opt_.crs);
    total_points_ += in.header.point_count;
    inputs_.push_back(std::move(in));
  }
  if (total_points_ == 0) {
    std::string names;
    for (const auto& in : inputs_) names += (names.empty() ? "" : ", ") + in.path;
    fail("{}: nothing to tile: the {} no points", names,
         inputs_.size() > 1 ? "inputs hold" : "input holds");
  }
  if (opt_.compression == "meshopt") {
    if (opt_.format != Format::Glb)
      fail("--compress meshopt is for glb output (EXT_meshopt_compression); pnts takes draco");
    content_.compression = Compression::Meshopt;
  } else if (opt_.compression == "draco") {
    if (opt_.format != Format::Pnts)
      fail(
          "--compress draco is for pnts output (3DTILES_draco_point_compression): glTF's Draco "
          "extension defines no point primitives; glb takes meshopt");
    content_.compression = Compression::Draco;
  } else if (opt_.compression != "none") {
    fail("--compress '{}' is not none, meshopt or draco", opt_.compression);
  }
  if (opt_.subtree_levels < 1 || opt_.subtree_levels > 16)
    fail("subtree levels {} is outside 1-16", opt_.subtree_levels);
  if (total_points_ >= (uint64_t(1) << 32) * 64) fail("too many points");
  content_.rgb = false, content_.gps_time = false;
  content_.precision = 1e300;
  for (const Input& in : inputs_) {
    content_.rgb |= in.header.has_rgb;
    content_.gps_time |= in.header.has_gps_time;
    const EcefTransform& t = thread_transform(in.crs);
    double h = std::min(in.header.scale.x, in.header.scale.y) * t.metres_per_unit();
    // Heights: in the horizontal unit for projected CRSs, metres for geographic ones.
    double v = in.header.scale.z * (t.geographic() ? 1.0 : t.metres_per_unit());
    content_.precision = std::min({content_.precision, h, v});
  }
}

void Tiler::to_local(const Input& in, io::PointBatch& batch, std::vector<glm::dvec3>& out) {
  Profiler::Scope scope(&prof_, Step::Transform);
  out.resize(batch.positions.size());
  LatticeStats stats;
  // A tenth of the input precision: the interpolation never shows in the output.
  source_to_local(thread_transform(in.crs), frame_, batch.positions.data(), out.size(), out.data(),
                  content_.precision / 10, &stats);
  std::lock_guard lock(lattice_mutex_);
  lattice_.points += stats.points;
  lattice_.exact_points += stats.exact_points;
  lattice_.nodes += stats.nodes;
  lattice_.max_sample_error = std::max(lattice_.max_sample_error, stats.max_sample_error);
}

void Tiler::make_records(const Input& in, io::PointBatch& batch, TilePoint* out) {
  thread_local std::vector<glm::dvec3> local;
  to_local(in, batch, local);
  const size_t n = batch.size();
  const bool rgb = !batch.rgb.empty(), gps = !batch.gps_time.empty();
  const bool inten = !batch.intensity.empty(), cls = !batch.classification.empty();
  const bool ret = !batch.return_number.empty();
  const int shift = in.header.rgb_bits == 8 ? 0 : 8;
  Profiler::Scope scope(&prof_, Step::Transform);
  for (size_t i = 0; i < n; ++i) {
    TilePoint& t = out[i];
    t.x = local[i].x, t.y = local[i].y, t.z = local[i].z;
    t.gps_time = gps ? batch.gps_time[i] : 0.0;
    t.intensity = inten ? batch.intensity[i] : 0;
    if (rgb) {
      t.r = uint8_t(std::min(255, batch.rgb[i].x >> shift));
      t.g = uint8_t(std::min(255, batch.rgb[i].y >> shift));
      t.b = uint8_t(std::min(255, batch.rgb[i].z >> shift));
    } else {
      t.r = t.g = t.b = 255;
    }
    t.classification = cls ? batch.classification[i] : 0;
    t.return_number = ret ? batch.return_number[i] : 0;
    t.pad = 0;
  }
}

// Sorts a block of records by chunk and appends each run to its chunk's temporary file.
void Tiler::append_to_chunks(const TilePoint* recs, size_t n) {
  thread_local std::vector<TilePoint> sorted;
  thread_local std::vector<int32_t> chunk_of;
  thread_local std::vector<uint32_t> offsets, fill;
  Profiler::Scope scope(&prof_, Step::Distribute);
  chunk_of.resize(n);
  offsets.assign(chunks_.size() + 1, 0);
  for (size_t i = 0; i < n; ++i) {
    chunk_of[i] = cell_chunk_[cell_of(recs[i])];
    STIPPLE_ASSERT(chunk_of[i] >= 0, "a counted cell has no chunk");
    ++offsets[size_t(chunk_of[i]) + 1];
  }
  for (size_t c = 0; c < chunks_.size(); ++c) offsets[c + 1] += offsets[c];
  fill.assign(offsets.begin(), offsets.end() - 1);
  sorted.resize(n);
  for (size_t i = 0; i < n; ++i) sorted[fill[size_t(chunk_of[i])]++] = recs[i];
  for (size_t c = 0; c < chunks_.size(); ++c) {
    uint32_t s = offsets[c], e = offsets[c + 1];
    if (s == e) continue;
    Chunk& ch = *chunks_[c];
    if (ch.resident) {
      // No lock: each writer reserves its own range of the chunk's counted place.
      const uint64_t at = ch.filled.fetch_add(e - s, std::memory_order_relaxed);
      if (at + (e - s) > ch.expected)
        fail("internal error: chunk {} receives more points than were counted", ch.key.name());
      std::memcpy(resident_.get() + ch.offset + at, sorted.data() + s,
                  size_t(e - s) * sizeof(TilePoint));
      continue;
    }
    std::unique_lock lock(ch.mutex);
    if (chunk_buffer_points_ == 0) {
      Profiler::Scope write(&prof_, Step::Write, size_t(e - s) * sizeof(TilePoint));
      append_file(ch.file, sorted.data() + s, size_t(e - s) * sizeof(TilePoint));
      ch.count += e - s;
    } else {
      // Fewer, larger writes: the chunk's records gather in its buffer (allocated once, at its
      // full size), and whoever would overfill it takes the full buffer, leaving its own empty
      // one of the same size, and appends it outside the lock; a run as large as a buffer is
      // appended directly. O_APPEND writes do not interleave; the order of records in a chunk
      // never mattered.
      const size_t run = e - s;
      ch.count += run;
      thread_local std::vector<TilePoint> full;
      full.clear();
      if (run >= chunk_buffer_points_) {
        lock.unlock();
        Profiler::Scope write(&prof_, Step::Write, run * sizeof(TilePoint));
        append_file(ch.file, sorted.data() + s, run * sizeof(TilePoint));
        continue;
      }
      if (ch.pending.capacity() < chunk_buffer_points_) ch.pending.reserve(chunk_buffer_points_);
      if (ch.pending.size() + run > chunk_buffer_points_) {
        full.reserve(chunk_buffer_points_);
        full.swap(ch.pending);
      }
      ch.pending.insert(ch.pending.end(), sorted.begin() + s, sorted.begin() + e);
      lock.unlock();
      if (full.empty()) continue;
      Profiler::Scope write(&prof_, Step::Write, full.size() * sizeof(TilePoint));
      append_file(ch.file, full.data(), full.size() * sizeof(TilePoint));
      full.clear();
    }
  }
}

// After a distribution pass: what the chunk buffers still hold goes to the files, in parallel.
void Tiler::flush_chunk_buffers() {
  pool_->parallel_for(chunks_.size(), 1, [&](size_t b, size_t e) {
    for (size_t c = b; c < e; ++c) {
      Chunk& ch = *chunks_[c];
      if (ch.pending.empty()) continue;
      Profiler::Scope write(&prof_, Step::Write, ch.pending.size() * sizeof(TilePoint));
      append_file(ch.file, ch.pending.data(), ch.pending.size() * sizeof(TilePoint));
      std::vector<TilePoint>().swap(ch.pending);
    }
  });
}

// Out of core, chunks are kept in memory while their records fit half the budget (the counting
// pass told their sizes exactly); only the rest go to temporary files. Temporary files cost
// a kernel copy in and out, and beyond a few hundred MB of dirty pages the kernel throttles
// writers to the disk's speed.
void Tiler::choose_resident_chunks(const std::vector<uint32_t>& counts) {
  for (size_t cell = 0; cell < counts.size(); ++cell)
    if (cell_chunk_[cell] >= 0) chunks_[size_t(cell_chunk_[cell])]->expected += counts[cell];
  const uint64_t budget = opt_.max_memory / 2 / sizeof(TilePoint);
  uint64_t total = 0;
  for (auto& c : chunks_) {
    if (total + c->expected > budget) continue;
    c->resident = true;
    c->offset = total;
    total += c->expected;
  }
  if (total) resident_.reset(new TilePoint[total]);
  // The other chunks gather records in buffers of together a sixteenth of the budget, when
  // that makes buffers of at least 10 kB; smaller ones would save few writes.
  size_t spilled = 0;
  for (auto& c : chunks_) spilled += !c->resident && c->expected > 0;
  if (spilled > 0) {
    const uint64_t per_chunk = opt_.max_memory / 16 / sizeof(TilePoint) / spilled;
    chunk_buffer_points_ = per_chunk >= 256 ? size_t(std::min<uint64_t>(per_chunk, 65536)) : 0;
  }
  STIPPLE_INFO("tile: {} of {} points in chunks held in memory, the rest in temporary files", total,
               total_points_);
}

// Distribution pass over staged records, in blocks read in parallel (pread).
void Tiler::distribute(const fs::path& staged, uint64_t count) {
  const FdCloser file{::open(staged.c_str(), O_RDONLY)};
  const int fd = file.fd;
  if (fd < 0) fail("{}: cannot open ({})", staged.string(), std::strerror(errno));
  const uint64_t block = batch_points_;
  const size_t blocks = size_t((count + block - 1) / block);
  Progress progress("distributing", count);
  pool_->parallel_for(blocks, 1, [&](size_t bb, size_t be) {
    thread_local std::vector<TilePoint> recs;
    for (size_t b = bb; b < be; ++b) {
      const uint64_t first = b * block;
      const size_t n = size_t(std::min<uint64_t>(block, count - first));
      recs.resize(n);
      char* dst = reinterpret_cast<char*>(recs.data());
      size_t want = n * sizeof(TilePoint);
      off_t at = off_t(first * sizeof(TilePoint));
      Profiler::Scope read(&prof_, Step::ReadDecode, want);
      while (want > 0) {
        ssize_t r = ::pread(fd, dst, want, at);
        if (r <= 0) fail("{}: cannot read temporary points", staged.string());
        dst += r, want -= size_t(r), at += r;
      }
      append_to_chunks(recs.data(), n);
      std::lock_guard lock(progress_mutex_);
      progress.advance(n);
    }
  });
  progress.finish();
}

// In-memory distribution: chunk of every staged record, per-block histograms, then a parallel
// scatter straight into each chunk's exact-size vector.
void Tiler::distribute_in_memory(uint64_t count) {
  const uint64_t block = batch_points_;
  const size_t blocks = size_t((count + block - 1) / block), nc = chunks_.size();
  const TilePoint* recs = staged_mem_.get();
  Profiler::Scope scope(&prof_, Step::Distribute);
  std::vector<uint32_t> chunk_of(count);
  std::vector<uint64_t> offsets(blocks * nc, 0);
  pool_->parallel_for(blocks, 1, [&](size_t bb, size_t be) {
    for (size_t b = bb; b < be; ++b) {
      uint64_t* hist = &offsets[b * nc];
      const uint64_t end = std::min<uint64_t>(count, (b + 1) * block);
      for (uint64_t i = b * block; i < end; ++i) {
        int32_t c = cell_chunk_[cell_of(recs[i])];
        STIPPLE_ASSERT(c >= 0, "a counted cell has no chunk");
        chunk_of[i] = uint32_t(c);
        ++hist[c];
      }
    }
  });
  uint64_t base = 0;
  for (size_t c = 0; c < nc; ++c) {
    Chunk& ch = *chunks_[c];
    ch.offset = base;
    for (size_t b = 0; b < blocks; ++b) {
      uint64_t h = offsets[b * nc + c];
      offsets[b * nc + c] = base;
      base += h;
    }
    ch.count = base - ch.offset;
    ch.resident = true;
  }
  resident_.reset(new TilePoint[count]);  // uninitialised: every slot is written below
  TilePoint* out = resident_.get();
  pool_->parallel_for(blocks, 1, [&](size_t bb, size_t be) {
    for (size_t b = bb; b < be; ++b) {
      uint64_t* fill = &offsets[b * nc];
      const uint64_t end = std::min<uint64_t>(count, (b + 1) * block);
      for (uint64_t i = b * block; i < end; ++i) out[fill[chunk_of[i]]++] = recs[i];
    }
  });
}

void Tiler::make_frame_and_cube() {
  // Frame origin: mean ECEF of the inputs' box centres.
  glm::dvec3 sum(0);
  for (const Input& in : inputs_) {
    glm::dvec3 c = (in.header.min + in.header.max) * 0.5;
    thread_transform(in.crs).transform(&c, 1);
    sum += c;
  }
  frame_ = make_local_frame(sum / double(inputs_.size()));
  // Box: header boxes sampled 9x9x3 through the transform (curvature, projection), padded.
  Box box;
  for (const Input& in : inputs_) {
    std::vector<glm::dvec3> s;
    for (int i = 0; i <= 8; ++i)
      for (int j = 0; j <= 8; ++j)
        for (int k = 0; k <= 2; ++k) {
          glm::dvec3 f(i / 8.0, j / 8.0, k / 2.0);
          s.push_back(in.header.min + (in.header.max - in.header.min) * f);
        }
    thread_transform(in.crs).transform(s.data(), s.size());
    for (const glm::dvec3& p : s) box.add(frame_.to_local(p));
  }
  glm::dvec3 ext = box.max - box.min;
  double size = std::max({ext.x, ext.y, ext.z, 1.0});
  size = size * 1.01 + 1.0;
  glm::dvec3 centre = (box.min + box.max) * 0.5;
  cube_min_ = centre - glm::dvec3(size * 0.5);
  cube_size_ = size;
  root_spacing_ = opt_.spacing > 0 ? opt_.spacing : size / 128.0;
  // Deep enough for any sane data; bounds recursion on duplicate points.
  max_level_ =
      std::clamp(int(std::ceil(std::log2(size / std::max(content_.precision, 1e-4)))) + 2, 4, 30);
}

// Every input is cut into ranges of about batch_points_ points (whole LAZ chunks for LAZ) and
// `process(input, batch)` runs for each range on the pool. Ranges are decoded on the workers by
// readers that seek, so LAZ decompression, the heaviest part of reading, uses every core. The
// ranges are the same in every pass (the lattice transform of a batch is then bit-identical).
template <typename Process>
void Tiler::read_pass(const char* label, Process process, bool positions_only) {
  Progress progress(label, total_points_);
  struct Range {
    size_t input;
    uint64_t first, count;
  };
  std::vector<Range> ranges;
  for (size_t k = 0; k < inputs_.size(); ++k) {
    const Input& in = inputs_[k];
    uint64_t step = batch_points_;
    if (const uint64_t chunk = in.header.compressed ? in.header.laz_chunk_points : 0)
      step = std::max<uint64_t>(1, step / chunk) * chunk;
    for (uint64_t first = 0; first < in.header.point_count; first += step)
      ranges.push_back({k, first, std::min(step, in.header.point_count - first)});
  }
  // Readers and batches are recycled: opening a reader parses the header and VLRs (and LASzip's
  // chunk table), and a fresh batch would fault in tens of MB of new pages each time.
  std::mutex mutex;
  std::vector<std::vector<std::unique_ptr<io::LasReader>>> readers(inputs_.size());
  std::vector<std::unique_ptr<io::PointBatch>> batches;
  std::atomic<uint64_t> done{0};
  pool_->parallel_for(ranges.size(), 1, [&](size_t b, size_t e) {
    for (size_t r = b; r < e; ++r) {
      const Range& range = ranges[r];
      const Input& in = inputs_[range.input];
      std::unique_ptr<io::LasReader> reader;
      std::unique_ptr<io::PointBatch> batch;
      {
        std::lock_guard lock(mutex);
        auto& idle = readers[range.input];
        if (!idle.empty()) reader = std::move(idle.back()), idle.pop_back();
        if (!batches.empty()) batch = std::move(batches.back()), batches.pop_back();
      }
      if (!reader) reader = std::make_unique<io::LasReader>(in.path);
      if (!batch) batch = std::make_unique<io::PointBatch>();
      {
        Profiler::Scope read(&prof_, Step::ReadDecode, range.count * in.header.point_record_length);
        batch->clear();
        reader->seek(range.first);
        const size_t got = positions_only ? reader->read_positions(batch->positions, range.count)
                                          : reader->read(*batch, range.count);
        if (got != range.count) fail("{}: holds fewer points than its header declares", in.path);
      }
      process(in, *batch);
      done += range.count;
      std::lock_guard lock(mutex);
      readers[range.input].push_back(std::move(reader));
      batches.push_back(std::move(batch));
      std::lock_guard progress_lock(progress_mutex_);
      progress.set(done.load());
      report(label, done.load(), total_points_);
    }
  });
  progress.finish();
}

void Tiler::plan_chunks(const std::vector<uint32_t>& counts) {
  // Count pyramid, level Lc at the bottom; then cut top-down.
  std::vector<std::vector<uint64_t>> pyramid(count_level_ + 1);
  pyramid[count_level_].assign(counts.begin(), counts.end());
  for (int l = count_level_ - 1; l >= 0; --l) {
    const uint32_t n = 1u << l;
    pyramid[l].assign(size_t(n) * n * n, 0);
    const auto& fine = pyramid[l + 1];
    for (uint32_t z = 0; z < 2 * n; ++z)
      for (uint32_t y = 0; y < 2 * n; ++y)
        for (uint32_t x = 0; x < 2 * n; ++x)
          pyramid[l][((z / 2) * n + y / 2) * n + x / 2] +=
              fine[(size_t(z) * 2 * n + y) * 2 * n + x];
  }
  cell_chunk_.assign(counts.size(), -1);
  std::vector<NodeKey> stack{NodeKey{}};
  while (!stack.empty()) {
    NodeKey k = stack.back();
    stack.pop_back();
    const uint32_t n = 1u << k.level;
    uint64_t c = pyramid[k.level][(size_t(k.z) * n + k.y) * n + k.x];
    if (c == 0) continue;
    if ((c > chunk_points_ || k.level < part_level_) && k.level < count_level_) {
      for (int i = 0; i < 8; ++i) stack.push_back(k.child(i));
      continue;
    }
    auto chunk = std::make_unique<Chunk>();
    chunk->key = k;
    chunk->file = tmp_ / ("chunk-" + k.name() + ".bin");
    // Mark the chunk's fine cells.
    const int shift = count_level_ - k.level;
    const uint32_t span = 1u << shift;
    for (uint32_t z = 0; z < span; ++z)
      for (uint32_t y = 0; y < span; ++y)
        for (uint32_t x = 0; x < span; ++x) {
          uint32_t cx = (k.x << shift) + x, cy = (k.y << shift) + y, cz = (k.z << shift) + z;
          cell_chunk_[(cz << (2 * count_level_)) | (cy << count_level_) | cx] =
              int32_t(chunks_.size());
        }
    chunks_.push_back(std::move(chunk));
  }
}

// A chunk over budget (a very dense fine cell) is split into its 8 children by streaming.
void Tiler::split_oversized_chunks() {
  for (size_t i = 0; i < chunks_.size(); ++i) {
    Chunk& c = *chunks_[i];
    if (c.count <= chunk_points_ * 3 / 2 || c.key.level >= max_level_ - 2) continue;
    if (c.resident) {
      write_file(c.file, resident_.get() + c.offset, c.count * sizeof(TilePoint));
      c.resident = false;
    }
    std::vector<std::unique_ptr<Chunk>> kids(8);
    for (int k = 0; k < 8; ++k) {
      kids[k] = std::make_unique<Chunk>();
      kids[k]->key = c.key.child(k);
      kids[k]->file = tmp_ / ("chunk-" + kids[k]->key.name() + ".bin");
    }
    glm::dvec3 centre = node_min(c.key) + glm::dvec3(node_size(c.key.level + 1));
    std::ifstream in(c.file, std::ios::binary);
    std::vector<TilePoint> block(1 << 16);
    std::vector<std::vector<TilePoint>> out(8);
    while (in) {
      in.read(reinterpret_cast<char*>(block.data()),
              std::streamsize(block.size() * sizeof(TilePoint)));
      size_t n = size_t(in.gcount()) / sizeof(TilePoint);
      for (size_t j = 0; j < n; ++j) {
        const TilePoint& p = block[j];
        out[(p.x >= centre.x) | ((p.y >= centre.y) << 1) | ((p.z >= centre.z) << 2)].push_back(p);
      }
      for (int k = 0; k < 8; ++k) {
        if (out[k].empty()) continue;
        append_file(kids[k]->file, out[k].data(), out[k].size() * sizeof(TilePoint));
        kids[k]->count += out[k].size();
        out[k].clear();
      }
    }
    in.close();
    fs::remove(c.file);
    chunks_.erase(chunks_.begin() + long(i));
    --i;
    for (auto& kid : kids)
      if (kid->count) chunks_.push_back(std::move(kid));
  }
}

void Tiler::record(const NodeKey& key, std::span<const TilePoint> pts) {
  NodeInfo info;
  info.points = pts.size();
  info.content = bounds_of(pts);
  std::lock_guard lock(nodes_mutex_);
  nodes_[key] = info;
}

void Tiler::write_content(const NodeKey& key, std::span<const TilePoint> pts) {
  record(key, pts);
  if (pts.empty()) return;
  std::vector<uint8_t> bytes;
  {
    Profiler::Scope encode(&prof_, Step::Encode);
    bytes = opt_.format == Format::Glb ? write_glb(pts, content_) : write_pnts(pts, content_);
  }
  const char* ext = opt_.format == Format::Glb ? ".glb" : ".pnts";
  Profiler::Scope write(&prof_, Step::Write, bytes.size());
  write_file(dir_ / "tiles" / (key.name() + ext), bytes.data(), bytes.size());
  written_ += pts.size();
}

// Works in place on its span: the points are partitioned into [child 0 .. child 7 | this node]
// and the children recurse on their sub-spans, so indexing allocates nothing per node.
void Tiler::index_node(const NodeKey& key, std::span<TilePoint> pts, bool chunk_root) {
  std::span<TilePoint> mine = pts;
  std::array<size_t, 9> starts{};
  if (pts.size() > opt_.max_node_points && key.level < max_level_) {
    thread_local std::vector<uint8_t> bucket;
    {
      Profiler::Scope sample(&prof_, Step::Sample);
      grid_select(pts, node_min(key), spacing(key.level), opt_.max_node_points, bucket);
    }
    Profiler::Scope index(&prof_, Step::Index);
    const glm::dvec3 centre = node_min(key) + glm::dvec3(node_size(key.level + 1));
    const size_t n = pts.size();
    std::array<size_t, 9> sizes{};
    for (size_t i = 0; i < n; ++i) {
      const TilePoint& p = pts[i];
      uint8_t b =
          bucket[i]
              ? 8
              : uint8_t((p.x >= centre.x) | ((p.y >= centre.y) << 1) | ((p.z >= centre.z) << 2));
      bucket[i] = b;
      ++sizes[b];
    }
    // American flag sort: each point swapped straight into its bucket's region.
    std::array<size_t, 9> next{}, ends{};
    for (size_t b = 0, at = 0; b < 9; ++b) starts[b] = next[b] = at, at += sizes[b], ends[b] = at;
    for (size_t b = 0; b < 9; ++b) {
      while (next[b] < ends[b]) {
        const uint8_t c = bucket[next[b]];
        if (c == b) {
          ++next[b];
        } else {
          std::swap(pts[next[b]], pts[next[c]]);
          std::swap(bucket[next[b]], bucket[next[c]]);
          ++next[c];
        }
      }
    }
    mine = pts.subspan(starts[8]);
  } else {
    starts.fill(pts.size());  // a leaf: no children
  }
  if (chunk_root) {
    // Its final content is known only after the upper levels took their share.
    fs::path file = tmp_ / ("root-" + key.name() + ".bin");
    {
      Profiler::Scope write(&prof_, Step::Write, mine.size() * sizeof(TilePoint));
      write_file(file, mine.data(), mine.size() * sizeof(TilePoint));
    }
    std::lock_guard lock(nodes_mutex_);
    pending_roots_[key] = file;
  } else {
    write_content(key, mine);
  }
  {
    std::lock_guard lock(progress_mutex_);
    index_progress_->advance(mine.size());
    indexed_ += mine.size();
    report("indexing", indexed_, total_points_);
  }
  for (int i = 0; i < 8; ++i) {
    const size_t b = starts[i], e = i == 7 ? starts[8] : starts[i + 1];
    if (e > b) index_node(key.child(i), pts.subspan(b, e - b), false);
  }
}

void Tiler::index_chunk(size_t i) {
  Chunk& c = *chunks_[i];
  thread_local std::vector<TilePoint> from_file;
  std::span<TilePoint> pts;
  if (c.resident) {
    pts = {resident_.get() + c.offset, c.count};
  } else {
    Profiler::Scope read(&prof_, Step::ReadDecode, c.count * sizeof(TilePoint));
    read_points(c.file, from_file);
    fs::remove(c.file);
    pts = from_file;
    if (pts.size() != c.count)
      fail("temporary chunk {} holds {} points, {} expected", c.key.name(), pts.size(), c.count);
  }
  index_node(c.key, pts, true);
}

void Tiler::build_upper_levels() {
  // The nodes above the chunk roots, down to the part level: every root deeper than that is
  // merged into its parent, and so is every parent made. Kids in key order, as ever.
  std::map<NodeKey, fs::path> file;  // of every root and every parent to make
  std::map<NodeKey, std::vector<NodeKey>> kids_of;
  for (auto& [k, f] : pending_roots_) file[k] = f;
  for (auto& [k, f] : pending_roots_) {
    for (NodeKey n = k; n.level > part_level_; n = n.parent()) {
      const NodeKey p = n.parent();
      const bool made_before = kids_of.count(p) > 0;
      kids_of[p].push_back(n);
      if (made_before) break;  // its ancestors are listed already
      if (file.count(p)) fail("internal error: chunk root {} lies above another", p.name());
      file[p] = tmp_ / ("root-" + p.name() + ".bin");
    }
  }
  if (!kids_of.empty()) {
    // A task graph, not a level at a time: a parent is built as soon as the last of its kids
    // is, so that no thread waits for a level's slowest parent (at 16 threads and 1,040 chunks,
    // levels with barriers kept the threads busy 64 % of this phase).
    std::map<NodeKey, int> waiting;  // kids not made yet
    // As many parents at once as their nodes fit a quarter of the budget (that is, with many
    // threads and a small budget, fewer than the pool; never none, which made this the longest
    // serial phase: 5-6 s of 8.5 on 16 threads, 100M points, 1,040 chunks). What a parent needs
    // is known when it is ready: its kids' files, copied twice, and up to the cap it passes up.
    const uint64_t quarter = opt_.max_memory / 4;
    auto bytes_for = [&](const NodeKey& parent) {
      uint64_t b = opt_.max_node_points * sizeof(TilePoint);
      for (const NodeKey& k : kids_of.at(parent)) {
        std::error_code ec;
        const uint64_t size = fs::file_size(file.at(k), ec);
        b += ec ? opt_.max_node_points * sizeof(TilePoint) : size;
      }
      return 2 * b;
    };
    std::vector<std::pair<NodeKey, uint64_t>> ready;  // and the bytes each needs
    for (auto& [p, kids] : kids_of) {
      std::sort(kids.begin(), kids.end());
      int w = 0;
      for (const NodeKey& k : kids) w += kids_of.count(k) ? 1 : 0;
      waiting[p] = w;
      if (w == 0) ready.emplace_back(p, bytes_for(p));
    }
    std::mutex mutex;
    std::condition_variable wake;
    size_t left = kids_of.size();
    bool failed = false;
    auto build = [&](const NodeKey& parent) {
      const std::vector<NodeKey>& kids = kids_of.at(parent);
      std::vector<size_t> ends;
      std::vector<TilePoint> all;
      for (const NodeKey& k : kids) {
        Profiler::Scope read(&prof_, Step::ReadDecode);
        std::vector<TilePoint> p = read_points(file.at(k));
        read.add_bytes(p.size() * sizeof(TilePoint));
        all.insert(all.end(), p.begin(), p.end());
        ends.push_back(all.size());
      }
      std::vector<uint8_t> selected;
      {
        Profiler::Scope sample(&prof_, Step::Sample);
        grid_select(all, node_min(parent), spacing(parent.level), opt_.max_node_points, selected);
      }
      std::vector<TilePoint> up;
      size_t at = 0;
      for (size_t c = 0; c < kids.size(); ++c) {
        std::vector<TilePoint> stay;
        for (; at < ends[c]; ++at) (selected[at] ? up : stay).push_back(all[at]);
        write_content(kids[c], stay);
        fs::remove(file.at(kids[c]));
      }
      Profiler::Scope write(&prof_, Step::Write, up.size() * sizeof(TilePoint));
      write_file(file.at(parent), up.data(), up.size() * sizeof(TilePoint));
    };
    uint64_t reserved = 0;
    size_t running = 0;
    // A budget that fits one parent of full kids at most runs them here, one at a time.
    const uint64_t full = 9 * opt_.max_node_points * sizeof(TilePoint) * 2;
    const size_t lanes =
        quarter / full <= 1 ? 1 : std::clamp<size_t>(pool_->size(), 1, kids_of.size());
    auto lane = [&](size_t, size_t) {
      std::unique_lock lock(mutex);
      while (true) {
        wake.wait(lock, [&] {
          return failed || left == 0 ||
                 (!ready.empty() && (running == 0 || reserved + ready.back().second <= quarter));
        });
        if (failed || left == 0) return;
        const auto [parent, need] = ready.back();
        ready.pop_back();
        reserved += need, ++running;
        lock.unlock();
        try {
          build(parent);
        } catch (...) {
          lock.lock();
          failed = true;
          wake.notify_all();
          throw;
        }
        lock.lock();
        reserved -= need, --running, --left;
        if (parent.level > part_level_ && --waiting.at(parent.parent()) == 0)
          ready.emplace_back(parent.parent(), bytes_for(parent.parent()));
        wake.notify_all();
      }
    };
    // One lane runs here: the memory freed by this thread is what it reuses (a worker's malloc
    // arena would keep its own, and a tight budget counts both).
    if (lanes == 1)
      lane(0, 1);
    else
      pool_->parallel_for(lanes, 1, lane);
    pending_roots_.clear();
    for (auto& [k, f] : file)
      if (k.level <= part_level_) pending_roots_[k] = f;
  }
  if (part_level_ > 0) return;  // the part roots stay raw: write_part keeps them for the merge
  for (auto& [k, f] : pending_roots_) {
    std::vector<TilePoint> pts;
    {
      Profiler::Scope read(&prof_, Step::ReadDecode);
      pts = read_points(f);
      read.add_bytes(pts.size() * sizeof(TilePoint));
    }
    write_content(k, pts);
    fs::remove(f);
  }
  pending_roots_.clear();
}

void Tiler::write_tileset() {
  using nlohmann::json;
  std::map<NodeKey, std::vector<NodeKey>> children;
  for (auto& [k, info] : nodes_)
    if (k.level > 0) children[k.parent()].push_back(k);
  // Boxes: content union children, padded a little so float rounding never leaves a point out.
  const double pad = std::max(0.001, content_.precision);
  const char* ext = opt_.format == Format::Glb ? ".glb" : ".pnts";
  std::function<json(const NodeKey&, Box&)> tile = [&](const NodeKey& k, Box& box) {
    const NodeInfo& info = nodes_.at(k);
    box = info.content;
    json kids = json::array();
    for (const NodeKey& c : children[k]) {
      Box cb;
      kids.push_back(tile(c, cb));
      box.add(cb);
    }
    glm::dvec3 lo = box.min - pad, hi = box.max + pad;
    glm::dvec3 c = (lo + hi) * 0.5, h = (hi - lo) * 0.5;
    json t = {{"boundingVolume", {{"box", {c.x, c.y, c.z, h.x, 0, 0, 0, h.y, 0, 0, 0, h.z}}}},
              {"geometricError", spacing(k.level)},
              {"refine", "ADD"}};
    if (info.points > 0) t["content"] = {{"uri", "tiles/" + k.name() + ext}};
    if (!kids.empty()) t["children"] = std::move(kids);
    return t;
  };
  json root;
  if (opt_.implicit) {
    root = write_implicit();
  } else {
    Box root_box;
    root = tile(NodeKey{}, root_box);
  }
  const glm::dmat3& m = frame_.enu_to_ecef;
  const glm::dvec3& o = frame_.origin_ecef;
  // Column-major ENU -> ECEF.
  root["transform"] = {m[0].x, m[0].y, m[0].z, 0, m[1].x, m[1].y, m[1].z, 0,
                       m[2].x, m[2].y, m[2].z, 0, o.x,    o.y,    o.z,    1};
  json tileset = {{"asset",
                   {{"version", opt_.format == Format::Glb || opt_.implicit ? "1.1" : "1.0"},
                    {"generator", "stipple tile"}}},
                  {"geometricError", 2 * root_spacing_},
                  {"root", root},
                  {"extras",
                   {{"stipple",
                     {{"points", total_points_},
                      {"rootSpacing", root_spacing_},
                      {"geometricErrorPerSpacing", 1.0},
                      {"cube", {cube_min_.x, cube_min_.y, cube_min_.z, cube_size_}}}}}}};
  std::string text = tileset.dump(1);
  Profiler::Scope write(&prof_, Step::Write, text.size());
  write_file(dir_ / "tileset.json", text.data(), text.size());
}

// Implicit octree over the cube: availability from the nodes (every node and its ancestors are
// tiles; those with points have content), in subtrees of S levels rooted at levels 0, S, 2S...
// Tile (level, x, y, z) is NodeKey{level, x, y, z}: the cube's subdivision, as implicit tiling
// subdivides the root box, with geometric error root / 2^level (the spacing halves per level).
nlohmann::json Tiler::write_implicit() {
  using nlohmann::json;
  std::map<NodeKey, bool> available;  // key -> has content
  int deepest = 0;
  for (auto& [k, info] : nodes_) {
    available[k] = available[k] || info.points > 0;
    deepest = std::max(deepest, k.level);
    for (NodeKey a = k; a.level > 0;) {
      a = a.parent();
      if (!available.emplace(a, false).second) break;
    }
  }
  const int levels = deepest + 1, S = std::min(opt_.subtree_levels, levels);
  struct Bits {
    std::vector<bool> tiles, content, children;
  };
  std::map<NodeKey, Bits> subtrees;
  const uint64_t tiles_per_subtree = io::subtree_tile_count(8, S);
  auto bits_of = [&](const NodeKey& root) -> Bits& {
    Bits& b = subtrees[root];
    if (b.tiles.empty()) {
      b.tiles.assign(tiles_per_subtree, false);
      b.content.assign(tiles_per_subtree, false);
      b.children.assign(size_t(1) << (3 * S), false);
    }
    return b;
  };
  for (auto& [k, has_content] : available) {
    const int base = k.level / S * S, local = k.level - base;
    const NodeKey root{base, k.x >> local, k.y >> local, k.z >> local};
    const uint64_t morton = io::morton_index(k.x - (root.x << local), k.y - (root.y << local),
                                             k.z - (root.z << local), 8);
    Bits& b = bits_of(root);
    const uint64_t index = io::availability_index(8, local, morton);
    b.tiles[index] = true;
    b.content[index] = has_content;
    if (local == 0 && k.level > 0) {
      // A subtree's root: available as a child subtree of the subtree above.
      const NodeKey parent{base - S, k.x >> S, k.y >> S, k.z >> S};
      bits_of(parent).children[io::morton_index(k.x - (parent.x << S), k.y - (parent.y << S),
                                                k.z - (parent.z << S), 8)] = true;
    }
  }
  fs::create_directories(dir_ / "subtrees");
  for (auto& [root, b] : subtrees) {
    std::vector<uint8_t> bytes = write_subtree(b.tiles, b.content, b.children);
    write_file(
        dir_ / "subtrees" / fmt::format("{}.{}.{}.{}.subtree", root.level, root.x, root.y, root.z),
        bytes.data(), bytes.size());
  }
  const double h = cube_size_ * 0.5;
  const glm::dvec3 c = cube_min_ + glm::dvec3(h);
  const char* ext = opt_.format == Format::Glb ? "glb" : "pnts";
  return {{"boundingVolume", {{"box", {c.x, c.y, c.z, h, 0, 0, 0, h, 0, 0, 0, h}}}},
          {"geometricError", spacing(0)},
          {"refine", "ADD"},
          {"content", {{"uri", fmt::format("tiles/{{level}}-{{x}}-{{y}}-{{z}}.{}", ext)}}},
          {"implicitTiling",
           {{"subdivisionScheme", "OCTREE"},
            {"subtreeLevels", S},
            {"availableLevels", levels},
            {"subtrees", {{"uri", "subtrees/{level}.{x}.{y}.{z}.subtree"}}}}}};
}

TileStats Tiler::run() {
  auto start = std::chrono::steady_clock::now();
  phase_start_ = start;
  phase("headers, frame, cube");
  if (opt_.subset_count) {
    const auto [index, count] =
        parse_subset(fmt::format("{}/{}", opt_.subset_index, opt_.subset_count));
    (void)index;
    // Octree nodes where N is a power of 8, else columns of a quadtree level.
    int l8 = 0, l4 = 0;
    for (uint64_t v = 1; v < count; v *= 8) ++l8;
    for (uint64_t v = 1; v < count; v *= 4) ++l4;
    if ((uint64_t(1) << (3 * l8)) == count) {
      part_level_ = l8;
    } else {
      part_level_ = l4;
      part_columns_ = true;
    }
  }
  const fs::path out = begin_output(opt_.output);
  open_inputs();
  make_frame_and_cube();

  unsigned threads =
      opt_.threads ? opt_.threads : std::max(1u, std::thread::hardware_concurrency());
  pool_ = std::make_unique<ThreadPool>(threads);
  prof_.attach(*pool_, opt_.sample_threads);
  // Memory plan (bytes per point in flight): a read batch ~170 (PointBatch + local positions +
  // records + sorted copy); a point being indexed ~120 (twice its record + hash slots).
  const uint64_t budget = opt_.max_memory;
  // Shares: 1/8 read batches, 1/4 indexing, the rest for the process itself, grids, allocator
  // slack and the upper levels.
  batch_points_ = std::clamp<uint64_t>(budget / 8 / ((threads + 2) * 170), 4096, 1 << 20);
  count_level_ = 7;
  while (count_level_ > 3 && (uint64_t(1) << (3 * count_level_)) * 8 > budget / 8) --count_level_;
  count_cells_ = double(1u << count_level_);
  chunk_points_ = std::max<uint64_t>(budget / 4 / (threads * 120), 20000);
  // Staged records and resident chunks (2 x 40 bytes a point) within half the budget.
  in_memory_ = total_points_ * 2 * sizeof(TilePoint) <= budget / 2;
  if (in_memory_) staged_mem_.reset(new TilePoint[total_points_]);
  if (part_level_ > count_level_)
    fail(
        "--subset {}/{}: parts of level {} are finer than the count grid (level {}); use fewer "
        "parts or a larger --max-memory",
        opt_.subset_index, opt_.subset_count, part_level_, count_level_);
  STIPPLE_INFO(
      "tile: {} points from {} input(s), cube {:.1f} m, root spacing {:.3f} m, precision {:.4f} m, "
      "batches of {}, count grid {}^3, chunks of <= {} points, {} threads",
      total_points_, inputs_.size(), cube_size_, root_spacing_, content_.precision, batch_points_,
      1 << count_level_, chunk_points_, threads);

  {
    // Three ways through the inputs (count cells, plan chunks, distribute to chunks):
    //  - in memory (the records fit half the budget twice): one reading pass stages records in
    //    memory; distribution scatters them into one resident array;
    //  - re-read (out of core, uncompressed LAS): a counting pass decodes and transforms
    //    positions only, a second pass decodes again and appends records to the chunk files.
    //    Decoding LAS from the page cache and the lattice transform cost less than writing and
    //    reading back a staging file of 40-byte records;
    //  - staged (out of core, LAZ in the inputs: decompressing twice would cost more): one
    //    reading pass writes records to a staging file, read back in parallel.
    const bool reread = !in_memory_ && std::none_of(inputs_.begin(), inputs_.end(),
                                                    [](auto& in) { return in.header.compressed; });
    phase(reread ? "read+decode+transform+count" : "read+decode+transform+stage+count");
    std::vector<std::atomic<uint32_t>> counts(size_t(1) << (3 * count_level_));
    const fs::path staged = tmp_ / "staged.bin";
    std::mutex stage_mutex;
    uint64_t staged_points = 0;
    if (reread) {
      // Positions only: counting needs nothing else, so the other fields are not decoded.
      read_pass(
          "counting",
          [&](const Input& in, io::PointBatch& batch) {
            thread_local std::vector<glm::dvec3> local;
            to_local(in, batch, local);
            Profiler::Scope count(&prof_, Step::Count);
            CellCounter counter(counts);
            for (const glm::dvec3& p : local)
              if (const uint32_t cell = cell_of(p); cell_in_part(cell)) counter.add(cell);
          },
          true);
    } else {
      int fd = -1;
      if (!in_memory_) {
        fd = ::open(staged.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
        if (fd < 0) fail("{}: cannot create ({})", staged.string(), std::strerror(errno));
      }
      const FdCloser closer{fd};
      read_pass("reading", [&](const Input& in, io::PointBatch& batch) {
        size_t n = batch.size();
        thread_local std::vector<TilePoint> local;
        TilePoint* recs = nullptr;
        if (in_memory_ && part_level_ == 0) {
          uint64_t at = staged_fill_.fetch_add(n);
          if (at + n > total_points_)
            fail("the inputs hold more points than the {} their headers declare", total_points_);
          recs = staged_mem_.get() + at;
          make_records(in, batch, recs);
        } else {
          local.resize(n);
          recs = local.data();
          make_records(in, batch, recs);
          n = keep_in_part(recs, n);
          if (in_memory_) {
            uint64_t at = staged_fill_.fetch_add(n);
            if (at + n > total_points_)
              fail("the inputs hold more points than the {} their headers declare", total_points_);
            std::memcpy(staged_mem_.get() + at, recs, n * sizeof(TilePoint));
            recs = staged_mem_.get() + at;
          }
        }
        {
          Profiler::Scope count(&prof_, Step::Count);
          CellCounter counter(counts);
          for (size_t i = 0; i < n; ++i) counter.add(cell_of(recs[i]));
        }
        if (in_memory_) return;
        Profiler::Scope write(&prof_, Step::Write, n * sizeof(TilePoint));
        std::lock_guard lock(stage_mutex);
        write_all(fd, staged, recs, n * sizeof(TilePoint));
        staged_points += n;
      });
    }
    if (in_memory_) staged_points = staged_fill_.load();
    STIPPLE_INFO(
        "tile: PROJ on {} lattice nodes for {} points ({} transformed point by point), largest "
        "sampled interpolation error {:.2e} m",
        lattice_.nodes, lattice_.points, lattice_.exact_points, lattice_.max_sample_error);
    phase("plan chunks");
    std::vector<uint32_t> plain(counts.size());
    for (size_t i = 0; i < counts.size(); ++i) plain[i] = counts[i].load();
    if (part_level_ > 0) {
      // From here on, the points are those of the part.
      total_points_ = 0;
      for (uint32_t c : plain) total_points_ += c;
      STIPPLE_INFO("tile: part {}/{} holds {} points", opt_.subset_index, opt_.subset_count,
                   total_points_);
    }
    std::vector<std::atomic<uint32_t>>().swap(counts);
    plan_chunks(plain);
    if (!in_memory_) choose_resident_chunks(plain);
    phase(reread ? "read+decode+transform+distribute" : "distribute");
    if (in_memory_) {
      distribute_in_memory(staged_points);
      staged_mem_.reset();
    } else if (reread) {
      read_pass("distributing", [&](const Input& in, io::PointBatch& batch) {
        thread_local std::vector<TilePoint> recs;
        recs.resize(batch.size());
        make_records(in, batch, recs.data());
        recs.resize(keep_in_part(recs.data(), recs.size()));
        append_to_chunks(recs.data(), recs.size());
      });
    } else {
      distribute(staged, staged_points);
      fs::remove(staged);
    }
    if (!in_memory_) flush_chunk_buffers();
    std::vector<int32_t>().swap(cell_chunk_);
    phase("split oversized chunks");
  }
  uint64_t distributed = 0;
  for (auto& c : chunks_) {
    if (!in_memory_ && c->resident) c->count = c->filled.load();
    distributed += c->count;
    if (!in_memory_ && c->resident && c->count != c->expected)
      fail("internal error: chunk {} holds {} points, {} were counted", c->key.name(), c->count,
           c->expected);
  }
  if (distributed != total_points_)
    fail("the inputs hold {} points, not the {} their headers declare", distributed, total_points_);
  split_oversized_chunks();
  phase("index+sample+encode+write");
  // Biggest chunks first keeps the pool busy to the end.
  std::sort(chunks_.begin(), chunks_.end(), [](auto& a, auto& b) { return a->count > b->count; });

  index_progress_ = std::make_unique<Progress>("indexing", total_points_);
  pool_->parallel_for(chunks_.size(), 1, [&](size_t b, size_t e) {
    for (size_t i = b; i < e; ++i) index_chunk(i);
  });
  resident_.reset();
  phase("upper levels");
  build_upper_levels();
  index_progress_->finish();
  phase(part_level_ > 0 ? "part.json" : "tileset.json");
  uint64_t kept_for_merge = 0;
  for (auto& [k, f] : pending_roots_) kept_for_merge += fs::file_size(f) / sizeof(TilePoint);
  if (written_ + kept_for_merge != total_points_)
    fail("internal error: {} points written, {} read", written_ + kept_for_merge, total_points_);
  if (part_level_ > 0)
    write_part();
  else
    write_tileset();
  fs::remove_all(tmp_);
  phase("commit");
  return commit(out, start);
}

fs::path Tiler::begin_output(const std::string& output) {
  fs::path out = fs::absolute(output).lexically_normal();
  if (out.filename().empty()) out = out.parent_path();
  if (fs::exists(out) && !opt_.force) fail("{} exists; pass --force to replace it", out.string());
  fs::path parent = out.parent_path();
  if (!fs::is_directory(parent)) fail("{}: no such directory", parent.string());
  std::string templ = (parent / (out.filename().string() + ".partial-XXXXXX")).string();
  if (!::mkdtemp(templ.data()))
    fail("cannot create a directory beside {} ({})", out.string(), std::strerror(errno));
  partial_ = std::make_unique<PartialDir>();
  partial_->path = templ;
  dir_ = partial_->path;
  tmp_ = dir_ / ".tmp";
  fs::create_directories(tmp_);
  fs::create_directories(dir_ / "tiles");
  return out;
}

TileStats Tiler::commit(const fs::path& out, std::chrono::steady_clock::time_point start) {
  // Commit: the finished directory replaces the output in one rename.
  if (fs::exists(out)) {
    fs::path old = out;
    old += fmt::format(".old-{}", ::getpid());
    fs::rename(out, old);
    fs::rename(dir_, out);
    fs::remove_all(old);
  } else {
    fs::rename(dir_, out);
  }
  partial_->committed = true;
  phase(nullptr);

  TileStats stats;
  stats.points = total_points_;
  stats.chunks = chunks_.size();
  stats.root_spacing = root_spacing_;
  for (auto& [k, info] : nodes_) {
    stats.tiles += info.points > 0;
    stats.depth = std::max(stats.depth, k.level);
  }
  stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  stats.threads = pool_ ? pool_->size() : 0;
  stats.phases = prof_.phases();
  for (size_t s = 0; s < step_count; ++s) stats.steps.push_back(prof_.step(Step(s)));
  return stats;
}

// A part's tiles, its roots' raw points (roots/LEVEL-X-Y-Z.bin) and part.json: what the merge
// needs to go on as build_tileset would above the part's nodes.
void Tiler::write_part() {
  using nlohmann::json;
  fs::create_directories(dir_ / "roots");
  json roots = json::array();
  for (auto& [k, f] : pending_roots_) {
    const uint64_t points = fs::file_size(f) / sizeof(TilePoint);
    fs::rename(f, dir_ / "roots" / (k.name() + ".bin"));
    roots.push_back({k.level, k.x, k.y, k.z, points});
  }
  pending_roots_.clear();
  json nodes = json::array();
  for (auto& [k, info] : nodes_) {
    const Box& b = info.content;
    nodes.push_back({k.level, k.x, k.y, k.z, info.points, b.min.x, b.min.y, b.min.z, b.max.x,
                     b.max.y, b.max.z});
  }
  const glm::dvec3& o = frame_.origin_ecef;
  json part = {{"stipple_part", 1},
               {"subset", {opt_.subset_index, opt_.subset_count}},
               {"level", part_level_},
               {"points", total_points_},
               {"inputs", opt_.inputs},
               {"format", opt_.format == Format::Glb ? "glb" : "pnts"},
               {"compression", opt_.compression},
               {"implicit", opt_.implicit},
               {"subtree_levels", opt_.subtree_levels},
               {"max_node_points", opt_.max_node_points},
               {"cube", {cube_min_.x, cube_min_.y, cube_min_.z, cube_size_}},
               {"root_spacing", root_spacing_},
               {"max_level", max_level_},
               {"precision", content_.precision},
               {"rgb", content_.rgb},
               {"gps_time", content_.gps_time},
               {"frame_origin", {o.x, o.y, o.z}},
               {"nodes", nodes},
               {"roots", roots}};
  const std::string text = part.dump(1);
  write_file(dir_ / "part.json", text.data(), text.size());
}

// Hard links where the file system allows (parts stay intact for a re-run), else copies. A
// file of that name from another part is refused, not replaced: two parts never hold one tile.
void link_or_copy(const fs::path& from, const fs::path& to, const fs::path& part) {
  std::error_code ec;
  if (fs::exists(fs::symlink_status(to, ec)))
    fail("{}: tile file {} is in another part too", part.string(), to.filename().string());
  fs::create_hard_link(from, to, ec);
  if (ec) fs::copy_file(from, to, fs::copy_options::none);
}

TileStats Tiler::merge(const std::vector<nlohmann::json>& parts,
                       const std::vector<fs::path>& dirs) {
  const auto start = std::chrono::steady_clock::now();
  phase_start_ = start;
  phase("read parts, link part tiles");
  const nlohmann::json& first = parts.front();
  auto vec = [](const nlohmann::json& a) {
    return glm::dvec3(a[0].get<double>(), a[1].get<double>(), a[2].get<double>());
  };
  cube_min_ = vec(first["cube"]);
  cube_size_ = first["cube"][3].get<double>();
  root_spacing_ = first["root_spacing"].get<double>();
  max_level_ = first["max_level"].get<int>();
  content_.precision = first["precision"].get<double>();
  content_.rgb = first["rgb"].get<bool>();
  content_.gps_time = first["gps_time"].get<bool>();
  content_.compression = opt_.compression == "meshopt" ? Compression::Meshopt
                         : opt_.compression == "draco" ? Compression::Draco
                                                       : Compression::None;
  frame_ = make_local_frame(vec(first["frame_origin"]));
  const fs::path out = begin_output(opt_.output);
  unsigned threads =
      opt_.threads ? opt_.threads : std::max(1u, std::thread::hardware_concurrency());
  pool_ = std::make_unique<ThreadPool>(threads);
  uint64_t tiles = 0;
  const int part_level = first["level"].get<int>();
  if (part_level < 1 || part_level > 15 || max_level_ < part_level || max_level_ > 30)
    fail("{}: part level {} or maximum level {} is out of range", dirs[0].string(), part_level,
         max_level_);
  // A key from a part.json: a node of the cube, below (or, for a root, at) the part level.
  auto key_of = [&](const nlohmann::json& a, bool root, const fs::path& dir) {
    const NodeKey k{a[0].get<int>(), a[1].get<uint32_t>(), a[2].get<uint32_t>(),
                    a[3].get<uint32_t>()};
    const bool level_ok = root ? k.level == part_level : k.level > part_level && k.level <= 30;
    const uint64_t n = level_ok ? uint64_t(1) << k.level : 0;
    if (!level_ok || k.x >= n || k.y >= n || k.z >= n)
      fail("{}: part.json names tile {}, outside the part's levels", dir.string(), k.name());
    return k;
  };
  for (size_t i = 0; i < parts.size(); ++i) {
    const nlohmann::json& p = parts[i];
    total_points_ += p["points"].get<uint64_t>();
    for (const auto& n : p["nodes"]) {
      const NodeKey k = key_of(n, false, dirs[i]);
      NodeInfo info;
      info.points = n[4].get<uint64_t>();
      if (info.points > 0) {
        info.content.min = glm::dvec3(n[5].get<double>(), n[6].get<double>(), n[7].get<double>());
        info.content.max = glm::dvec3(n[8].get<double>(), n[9].get<double>(), n[10].get<double>());
      }
      if (nodes_.count(k)) fail("{}: tile {} is in another part too", dirs[i].string(), k.name());
      nodes_[k] = info;
      written_ += info.points;
    }
    if (fs::is_directory(dirs[i] / "tiles"))
      for (const auto& e : fs::directory_iterator(dirs[i] / "tiles")) {
        link_or_copy(e.path(), dir_ / "tiles" / e.path().filename(), dirs[i]);
        ++tiles;
      }
    for (const auto& r : p["roots"]) {
      const NodeKey k = key_of(r, true, dirs[i]);
      if (pending_roots_.count(k))
        fail("{}: root {} is in another part too", dirs[i].string(), k.name());
      const fs::path from = dirs[i] / "roots" / (k.name() + ".bin");
      if (!fs::exists(from) || fs::file_size(from) != r[4].get<uint64_t>() * sizeof(TilePoint))
        fail("{}: {} is missing or not of {} points", dirs[i].string(), from.string(),
             r[4].get<uint64_t>());
      const fs::path to = tmp_ / ("root-" + k.name() + ".bin");
      fs::copy_file(from, to);  // build_upper_levels consumes it
      pending_roots_[k] = to;
    }
    report("merging", i + 1, parts.size());
  }
  STIPPLE_INFO("tile merge: {} parts, {} points, {} tiles linked", parts.size(), total_points_,
               tiles);
  phase("upper levels");
  index_progress_ = std::make_unique<Progress>("upper levels", total_points_);
  build_upper_levels();
  index_progress_->finish();
  phase("tileset.json");
  if (written_ != total_points_)
    fail("tile merge: the parts' tiles and roots hold {} points, their part.json files say {}",
         written_.load(), total_points_);
  if (total_points_ == 0 || !nodes_.count(NodeKey{})) fail("tile merge: the parts hold no points");
  for (const auto& [k, info] : nodes_)
    if (k.level > 0 && !nodes_.count(k.parent()))
      fail("tile merge: tile {} has no parent in any part", k.name());
  write_tileset();
  fs::remove_all(tmp_);
  phase("commit");
  return commit(out, start);
}

}  // namespace

TileStats build_tileset(const TileOptions& options) {
  Tiler tiler(options);
  return tiler.run();
}

std::pair<uint32_t, uint32_t> parse_subset(const std::string& text) {
  const size_t slash = text.find('/');
  uint64_t index = 0, count = 0;
  bool ok = slash != std::string::npos && slash > 0 && slash + 1 < text.size();
  for (size_t i = 0; ok && i < text.size(); ++i) {
    if (i == slash) continue;
    if (text[i] < '0' || text[i] > '9' || (i < slash ? index : count) > (1u << 30)) {
      ok = false;
      break;
    }
    uint64_t& v = i < slash ? index : count;
    v = v * 10 + uint64_t(text[i] - '0');
  }
  bool power = false;
  for (uint64_t v = 4; ok && v <= count; v *= 4) power |= v == count;
  for (uint64_t v = 8; ok && v <= count; v *= 8) power |= v == count;
  if (!ok || !power || index >= count)
    fail("--subset '{}' is not I/N with N a power of 4 or 8 (4, 8, 16, 64, ...) and 0 <= I < N",
         text);
  return {uint32_t(index), uint32_t(count)};
}

namespace {

// Whether part.json has the shape write_part gives it: integers where integers are read (a
// double read as an integer out of its range would be undefined behaviour), numbers, strings
// and booleans elsewhere.
bool part_json_shape_ok(const nlohmann::json& p) {
  auto uints = [](const nlohmann::json& a, size_t from, size_t to) {
    for (size_t i = from; i < to; ++i)
      if (!a[i].is_number_unsigned()) return false;
    return true;
  };
  auto numbers = [](const nlohmann::json& a, size_t from, size_t to) {
    for (size_t i = from; i < to; ++i)
      if (!a[i].is_number()) return false;
    return true;
  };
  auto array_of = [](const nlohmann::json& a, size_t n) { return a.is_array() && a.size() == n; };
  if (!p.is_object()) return false;
  for (const char* key :
       {"subset", "level", "points", "inputs", "format", "compression", "implicit",
        "subtree_levels", "max_node_points", "cube", "root_spacing", "max_level", "precision",
        "rgb", "gps_time", "frame_origin", "nodes", "roots"})
    if (!p.contains(key)) return false;
  for (const char* key : {"level", "points", "subtree_levels", "max_node_points", "max_level"})
    if (!p[key].is_number_unsigned()) return false;
  if (!array_of(p["subset"], 2) || !uints(p["subset"], 0, 2)) return false;
  if (!array_of(p["cube"], 4) || !numbers(p["cube"], 0, 4)) return false;
  if (!array_of(p["frame_origin"], 3) || !numbers(p["frame_origin"], 0, 3)) return false;
  if (!p["root_spacing"].is_number() || !p["precision"].is_number()) return false;
  if (!p["nodes"].is_array() || !p["roots"].is_array() || !p["inputs"].is_array()) return false;
  for (const auto& n : p["nodes"])
    if (!array_of(n, 11) || !uints(n, 0, 5) || !numbers(n, 5, 11)) return false;
  for (const auto& r : p["roots"])
    if (!array_of(r, 5) || !uints(r, 0, 5)) return false;
  return p["subtree_levels"].get<uint64_t>() <= 16 && p["level"].get<uint64_t>() <= 30 &&
         p["max_level"].get<uint64_t>() <= 30;
}

// The numbers the merge computes with, in the ranges a tiling gives them: a cube of finite
// corner and an edge of 1 m to 10^8 m (make_frame_and_cube makes it at least 2 m), a root
// spacing between edge / 2^20 and 10^8 m, a positive finite precision and frame origin.
void check_part_ranges(const nlohmann::json& p, const fs::path& file) {
  const auto& c = p["cube"];
  const double edge = c[3].get<double>(), spacing = p["root_spacing"].get<double>(),
               precision = p["precision"].get<double>();
  bool finite = std::isfinite(precision);
  for (size_t i = 0; i < 3; ++i)
    finite = finite && std::isfinite(c[i].get<double>()) && std::abs(c[i].get<double>()) <= 1e9 &&
             std::isfinite(p["frame_origin"][i].get<double>());
  if (!finite || !(edge >= 1.0 && edge <= 1e8))
    fail("{}: cube [{}, {}, {}] of edge {} (or frame origin) is out of range (edge 1 m to 1e8 m)",
         file.string(), c[0].get<double>(), c[1].get<double>(), c[2].get<double>(), edge);
  if (!(spacing >= edge / double(1 << 20) && spacing <= 1e8))
    fail("{}: root spacing {} is out of range (cube edge / 2^20 = {} to 1e8 m)", file.string(),
         spacing, edge / double(1 << 20));
  if (!(precision > 0))
    fail("{}: precision {} is out of range (positive and finite)", file.string(), precision);
}

TileStats merge_parts_checked(const MergeOptions& options) {
  if (options.parts.empty()) fail("tile merge: no parts");
  std::vector<nlohmann::json> parts;
  std::vector<fs::path> dirs;
  std::set<uint32_t> seen;
  uint32_t count = 0;
  for (const std::string& dir : options.parts) {
    const fs::path file = fs::path(dir) / "part.json";
    std::ifstream in(file);
    if (!in) fail("{}: not a part of a split tiling (no part.json; made by tile --subset)", dir);
    nlohmann::json p = nlohmann::json::parse(in, nullptr, false);
    if (p.is_discarded() || !p.is_object() || !p.contains("stipple_part") ||
        p["stipple_part"] != 1 || !part_json_shape_ok(p))
      fail("{}: not a part.json written by stipple tile --subset", file.string());
    const uint32_t index = p["subset"][0].get<uint32_t>(), n = p["subset"][1].get<uint32_t>();
    try {
      parse_subset(fmt::format("{}/{}", index, n));  // N a power of 4 or 8, I < N
    } catch (const Error&) {
      fail("{}: part {}/{} is not one of N parts with N a power of 4 or 8", dir, index, n);
    }
    if (count == 0) count = n;
    if (n != count)
      fail("{}: part {}/{} of another split (the first part is of {})", dir, index, n, count);
    if (!seen.insert(index).second) fail("{}: part {}/{} is given twice", dir, index, n);
    check_part_ranges(p, file);
    if (!parts.empty()) {
      for (const char* key : {"cube", "root_spacing", "format", "compression", "implicit",
                              "subtree_levels", "max_node_points", "frame_origin", "precision",
                              "rgb", "gps_time", "level", "max_level"})
        if (p[key] != parts.front()[key])
          fail("{}: its {} differs from {}'s: the parts are of different tilings", dir, key,
               options.parts.front());
      // Inputs by file name: parts tiled on other machines see the same files under other
      // mounts or relative paths; the cube, equal above, ties them to the same data.
      auto names = [](const nlohmann::json& inputs) {
        std::vector<std::string> n;
        for (const auto& in : inputs) n.push_back(fs::path(in.get<std::string>()).filename());
        return n;
      };
      if (names(p["inputs"]) != names(parts.front()["inputs"]))
        fail("{}: its inputs differ from {}'s: the parts are of different tilings", dir,
             options.parts.front());
    }
    parts.push_back(std::move(p));
    dirs.push_back(dir);
  }
  if (seen.size() != count) {
    std::string missing;
    for (uint32_t i = 0; i < count && missing.size() < 200; ++i)
      if (!seen.count(i)) missing += (missing.empty() ? "" : ", ") + fmt::format("{}/{}", i, count);
    fail("tile merge: {} of {} parts given; missing {}", seen.size(), count, missing);
  }
  TileOptions o;
  o.output = options.output;
  o.force = options.force;
  o.threads = options.threads;
  o.max_memory = options.max_memory;
  o.progress = options.progress;
  const nlohmann::json& f = parts.front();
  o.format = f["format"] == "pnts" ? Format::Pnts : Format::Glb;
  o.compression = f["compression"].get<std::string>();
  o.implicit = f["implicit"].get<bool>();
  o.subtree_levels = f["subtree_levels"].get<int>();
  o.max_node_points = f["max_node_points"].get<size_t>();
  // Every part names the same inputs (checked above): the split tiled them once.
  for (const auto& in : f["inputs"]) o.inputs.push_back(in.get<std::string>());
  Tiler tiler(o);
  return tiler.merge(parts, dirs);
}

}  // namespace

TileStats merge_parts(const MergeOptions& options) {
  try {
    return merge_parts_checked(options);
  } catch (const nlohmann::json::exception& e) {
    fail("tile merge: a part.json is malformed ({}): not written by stipple tile --subset",
         e.what());
  }
}

std::string profile_table(const TileStats& stats) {
  std::string out = fmt::format(
      "| phase | wall s | CPU s | sys s | CPU s per thread (main, workers) | CPU/wall | one "
      "thread "
      "s | read MB | written MB | minor faults |\n|---|--:|--:|--:|---|--:|--:|--:|--:|--:|\n");
  PhaseProfile total;
  total.name = "total";
  for (const PhaseProfile& p : stats.phases) {
    std::string per;
    for (double c : p.thread_cpu) per += fmt::format("{}{:.2f}", per.empty() ? "" : " ", c);
    out += fmt::format(
        "| {} | {:.3f} | {:.2f} | {:.2f} | {} | {:.2f} | {:.3f} | {:.1f} | {:.1f} | {} |\n", p.name,
        p.wall, p.cpu(), p.sys, per, p.wall > 0 ? p.cpu() / p.wall : 0.0, p.one_thread,
        double(p.bytes_read) / 1e6, double(p.bytes_written) / 1e6, p.minor_faults);
    total.wall += p.wall, total.user += p.user, total.sys += p.sys;
    total.one_thread += p.one_thread;
    total.bytes_read += p.bytes_read, total.bytes_written += p.bytes_written;
    total.minor_faults += p.minor_faults;
  }
  out += fmt::format(
      "| total | {:.3f} | {:.2f} | {:.2f} | | {:.2f} | {:.3f} | {:.1f} | {:.1f} | {} |\n",
      total.wall, total.cpu(), total.sys, total.wall > 0 ? total.cpu() / total.wall : 0.0,
      total.one_thread, double(total.bytes_read) / 1e6, double(total.bytes_written) / 1e6,
      total.minor_faults);
  out += "\n| step | thread s | CPU s | MB |\n|---|--:|--:|--:|\n";
  for (size_t s = 0; s < stats.steps.size(); ++s)
    out += fmt::format("| {} | {:.3f} | {:.3f} | {:.1f} |\n", step_name(Step(s)),
                       stats.steps[s].thread_seconds, stats.steps[s].cpu,
                       double(stats.steps[s].bytes) / 1e6);
  return out;
}

std::string stats_json(const TileStats& stats) {
  using nlohmann::json;
  json phases = json::array();
  for (const PhaseProfile& p : stats.phases)
    phases.push_back({{"name", p.name},
                      {"wall", p.wall},
                      {"user", p.user},
                      {"sys", p.sys},
                      {"threadCpu", p.thread_cpu},
                      {"oneThread", p.one_thread},
                      {"noThread", p.no_thread},
                      {"bytesRead", p.bytes_read},
                      {"bytesWritten", p.bytes_written},
                      {"minorFaults", p.minor_faults},
                      {"majorFaults", p.major_faults},
                      {"voluntarySwitches", p.voluntary_switches},
                      {"involuntarySwitches", p.involuntary_switches}});
  json steps = json::object();
  for (size_t s = 0; s < stats.steps.size(); ++s)
    steps[step_name(Step(s))] = {{"threadSeconds", stats.steps[s].thread_seconds},
                                 {"cpu", stats.steps[s].cpu},
                                 {"bytes", stats.steps[s].bytes}};
  json j = {{"points", stats.points},
            {"tiles", stats.tiles},
            {"depth", stats.depth},
            {"chunks", stats.chunks},
            {"rootSpacing", stats.root_spacing},
            {"seconds", stats.seconds},
            {"pointsPerSecond", stats.seconds > 0 ? double(stats.points) / stats.seconds : 0.0},
            {"threads", stats.threads},
            {"phases", phases},
            {"steps", steps}};
  return j.dump(1) + "\n";
}

}  // namespace stipple::tiler
