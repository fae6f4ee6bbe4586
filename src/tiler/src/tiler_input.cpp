#include "tiler_input.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <map>
#include <memory>
#include <mutex>

#include "stipple/core/error.hpp"
#include "stipple/core/log.hpp"
#include "tiler_chunks.hpp"
#include "tiler_files.hpp"

namespace stipple::tiler::detail {

namespace {

// One EcefTransform per thread and CRS (PROJ objects are not thread-safe).
const EcefTransform& thread_transform(const std::string& crs) {
  thread_local std::map<std::string, std::unique_ptr<EcefTransform>> cache;
  auto& t = cache[crs];
  if (!t) t = std::make_unique<EcefTransform>(crs);
  return *t;
}

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

void to_local(Build& b, const Input& in, io::PointBatch& batch, std::vector<glm::dvec3>& out) {
  Profiler::Scope scope(&b.prof, Step::Transform);
  out.resize(batch.positions.size());
  LatticeStats stats;
  // A tenth of the input precision: the interpolation never shows in the output.
  source_to_local(thread_transform(in.crs), b.frame, batch.positions.data(), out.size(), out.data(),
                  b.content.precision / 10, &stats);
  std::lock_guard lock(b.lattice_mutex);
  b.lattice.points += stats.points;
  b.lattice.exact_points += stats.exact_points;
  b.lattice.nodes += stats.nodes;
  b.lattice.max_sample_error = std::max(b.lattice.max_sample_error, stats.max_sample_error);
}

void make_records(Build& b, const Input& in, io::PointBatch& batch, TilePoint* out) {
  thread_local std::vector<glm::dvec3> local;
  to_local(b, in, batch, local);
  const size_t n = batch.size();
  const bool rgb = !batch.rgb.empty(), gps = !batch.gps_time.empty();
  const bool inten = !batch.intensity.empty(), cls = !batch.classification.empty();
  const bool ret = !batch.return_number.empty();
  const int shift = in.header.rgb_bits == 8 ? 0 : 8;
  Profiler::Scope scope(&b.prof, Step::Transform);
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

// Every input is cut into ranges of about batch_points points (whole LAZ chunks for LAZ) and
// `process(input, batch)` runs for each range on the pool. Ranges are decoded on the workers by
// readers that seek, so LAZ decompression, the heaviest part of reading, uses every core. The
// ranges are the same in every pass (the lattice transform of a batch is then bit-identical).
template <typename Process>
void read_pass(Build& b, const char* label, Process process, bool positions_only = false) {
  Progress progress(label, b.total_points);
  struct Range {
    size_t input;
    uint64_t first, count;
  };
  std::vector<Range> ranges;
  for (size_t k = 0; k < b.inputs.size(); ++k) {
    const Input& in = b.inputs[k];
    uint64_t step = b.batch_points;
    if (const uint64_t chunk = in.header.compressed ? in.header.laz_chunk_points : 0)
      step = std::max<uint64_t>(1, step / chunk) * chunk;
    for (uint64_t first = 0; first < in.header.point_count; first += step)
      ranges.push_back({k, first, std::min(step, in.header.point_count - first)});
  }
  // Readers and batches are recycled: opening a reader parses the header and VLRs (and LASzip's
  // chunk table), and a fresh batch would fault in tens of MB of new pages each time.
  std::mutex mutex;
  std::vector<std::vector<std::unique_ptr<io::LasReader>>> readers(b.inputs.size());
  std::vector<std::unique_ptr<io::PointBatch>> batches;
  std::atomic<uint64_t> done{0};
  b.pool->parallel_for(ranges.size(), 1, [&](size_t rb, size_t re) {
    for (size_t r = rb; r < re; ++r) {
      const Range& range = ranges[r];
      const Input& in = b.inputs[range.input];
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
        Profiler::Scope read(&b.prof, Step::ReadDecode,
                             range.count * in.header.point_record_length);
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
      std::lock_guard progress_lock(b.progress_mutex);
      progress.set(done.load());
      report(b, label, done.load(), b.total_points);
    }
  });
  progress.finish();
}

}  // namespace

void open_inputs(Build& b) {
  const TileOptions& opt = b.opt;
  if (opt.inputs.empty()) fail("no input files");
  for (const std::string& path : opt.inputs) {
    Input in;
    in.path = path;
    in.header = io::read_las_header(path);
    if (const std::string problem = io::geographic_bounds_problem(in.header);
        !problem.empty() && opt.crs.empty())
      fail("{}", problem);
    // The reader detects 8-bit colour stored in 16-bit fields from the first points
    // (read_las_header cannot): make_records scales by it.
    if (in.header.has_rgb) in.header.rgb_bits = io::LasReader(path).header().rgb_bits;
    in.crs = source_crs_definition(in.header, opt.crs);
    b.total_points += in.header.point_count;
    b.inputs.push_back(std::move(in));
  }
  if (b.total_points == 0) {
    std::string names;
    for (const auto& in : b.inputs) names += (names.empty() ? "" : ", ") + in.path;
    fail("{}: nothing to tile: the {} no points", names,
         b.inputs.size() > 1 ? "inputs hold" : "input holds");
  }
  ContentOptions& content = b.content;
  if (opt.compression == "meshopt") {
    if (opt.format != Format::Glb)
      fail("--compress meshopt is for glb output (EXT_meshopt_compression); pnts takes draco");
    content.compression = Compression::Meshopt;
  } else if (opt.compression == "draco") {
    if (opt.format != Format::Pnts)
      fail(
          "--compress draco is for pnts output (3DTILES_draco_point_compression): glTF's Draco "
          "extension defines no point primitives; glb takes meshopt");
    content.compression = Compression::Draco;
  } else if (opt.compression != "none") {
    fail("--compress '{}' is not none, meshopt or draco", opt.compression);
  }
  if (opt.subtree_levels < 1 || opt.subtree_levels > 16)
    fail("subtree levels {} is outside 1-16", opt.subtree_levels);
  if (b.total_points >= (uint64_t(1) << 32) * 64) fail("too many points");
  content.rgb = false, content.gps_time = false;
  content.precision = 1e300;
  for (const Input& in : b.inputs) {
    content.rgb |= in.header.has_rgb;
    content.gps_time |= in.header.has_gps_time;
    const EcefTransform& t = thread_transform(in.crs);
    double h = std::min(in.header.scale.x, in.header.scale.y) * t.metres_per_unit();
    // Heights: in the horizontal unit for projected CRSs, metres for geographic ones.
    double v = in.header.scale.z * (t.geographic() ? 1.0 : t.metres_per_unit());
    content.precision = std::min({content.precision, h, v});
  }
}

void make_frame_and_cube(Build& b) {
  // Frame origin: mean ECEF of the inputs' box centres.
  glm::dvec3 sum(0);
  for (const Input& in : b.inputs) {
    glm::dvec3 c = (in.header.min + in.header.max) * 0.5;
    thread_transform(in.crs).transform(&c, 1);
    sum += c;
  }
  b.frame = make_local_frame(sum / double(b.inputs.size()));
  // Box: header boxes sampled 9x9x3 through the transform (curvature, projection), padded.
  Box box;
  for (const Input& in : b.inputs) {
    std::vector<glm::dvec3> s;
    for (int i = 0; i <= 8; ++i)
      for (int j = 0; j <= 8; ++j)
        for (int k = 0; k <= 2; ++k) {
          glm::dvec3 f(i / 8.0, j / 8.0, k / 2.0);
          s.push_back(in.header.min + (in.header.max - in.header.min) * f);
        }
    thread_transform(in.crs).transform(s.data(), s.size());
    for (const glm::dvec3& p : s) box.add(b.frame.to_local(p));
  }
  glm::dvec3 ext = box.max - box.min;
  double size = std::max({ext.x, ext.y, ext.z, 1.0});
  size = size * 1.01 + 1.0;
  glm::dvec3 centre = (box.min + box.max) * 0.5;
  b.cube_min = centre - glm::dvec3(size * 0.5);
  b.cube_size = size;
  b.root_spacing = b.opt.spacing > 0 ? b.opt.spacing : size / 128.0;
  // Deep enough for any sane data; bounds recursion on duplicate points.
  b.max_level =
      std::clamp(int(std::ceil(std::log2(size / std::max(b.content.precision, 1e-4)))) + 2, 4, 30);
}

uint64_t read_and_count(Build& b, bool reread, std::vector<std::atomic<uint32_t>>& counts,
                        const fs::path& staged) {
  std::mutex stage_mutex;
  uint64_t staged_points = 0;
  if (reread) {
    // Positions only: counting needs nothing else, so the other fields are not decoded.
    read_pass(
        b, "counting",
        [&](const Input& in, io::PointBatch& batch) {
          thread_local std::vector<glm::dvec3> local;
          to_local(b, in, batch, local);
          Profiler::Scope count(&b.prof, Step::Count);
          CellCounter counter(counts);
          for (const glm::dvec3& p : local)
            if (const uint32_t cell = cell_of(b, p); cell_in_part(b, cell)) counter.add(cell);
        },
        true);
  } else {
    int fd = -1;
    if (!b.in_memory) {
      fd = ::open(staged.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      if (fd < 0) fail("{}: cannot create ({})", staged.string(), std::strerror(errno));
    }
    const FdCloser closer{fd};
    read_pass(b, "reading", [&](const Input& in, io::PointBatch& batch) {
      size_t n = batch.size();
      thread_local std::vector<TilePoint> local;
      TilePoint* recs = nullptr;
      if (b.in_memory && b.part_level == 0) {
        uint64_t at = b.staged_fill.fetch_add(n);
        if (at + n > b.total_points)
          fail("the inputs hold more points than the {} their headers declare", b.total_points);
        recs = b.staged_mem.get() + at;
        make_records(b, in, batch, recs);
      } else {
        local.resize(n);
        recs = local.data();
        make_records(b, in, batch, recs);
        n = keep_in_part(b, recs, n);
        if (b.in_memory) {
          uint64_t at = b.staged_fill.fetch_add(n);
          if (at + n > b.total_points)
            fail("the inputs hold more points than the {} their headers declare", b.total_points);
          std::memcpy(b.staged_mem.get() + at, recs, n * sizeof(TilePoint));
          recs = b.staged_mem.get() + at;
        }
      }
      {
        Profiler::Scope count(&b.prof, Step::Count);
        CellCounter counter(counts);
        for (size_t i = 0; i < n; ++i) counter.add(cell_of(b, recs[i]));
      }
      if (b.in_memory) return;
      Profiler::Scope write(&b.prof, Step::Write, n * sizeof(TilePoint));
      std::lock_guard lock(stage_mutex);
      write_all(fd, staged, recs, n * sizeof(TilePoint));
      staged_points += n;
    });
  }
  if (b.in_memory) staged_points = b.staged_fill.load();
  STIPPLE_INFO(
      "tile: PROJ on {} lattice nodes for {} points ({} transformed point by point), largest "
      "sampled interpolation error {:.2e} m",
      b.lattice.nodes, b.lattice.points, b.lattice.exact_points, b.lattice.max_sample_error);
  return staged_points;
}

void reread_and_distribute(Build& b) {
  read_pass(b, "distributing", [&](const Input& in, io::PointBatch& batch) {
    thread_local std::vector<TilePoint> recs;
    recs.resize(batch.size());
    make_records(b, in, batch, recs.data());
    recs.resize(keep_in_part(b, recs.data(), recs.size()));
    append_to_chunks(b, recs.data(), recs.size());
  });
}

}  // namespace stipple::tiler::detail
