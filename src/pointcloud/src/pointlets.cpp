#include "stipple/pointcloud/pointlets.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <optional>
#include <queue>
#include <random>

#include "stipple/core/atomic_file.hpp"
#include "stipple/core/error.hpp"
#include "stipple/core/log.hpp"
#include "stipple/core/progress.hpp"
#include "stipple/core/thread_pool.hpp"
#include "stipple/io/las.hpp"
#include "stipple/math/geo.hpp"

namespace stipple::pc {
namespace fs = std::filesystem;

namespace {

constexpr char kMagic[8] = {'S', 'T', 'P', 'L', 'T', 'C', 'H', 'E'};
constexpr uint32_t kGridBits = 10;  // per axis: 30-bit Morton / Hilbert keys
constexpr uint64_t kMaxSources = 64;

using Clock = std::chrono::steady_clock;
double since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

uint32_t crc32_of(const void* data, uint64_t size, uint32_t crc = 0) {
  const auto* p = static_cast<const Bytef*>(data);
  while (size > 0) {
    const uInt n = uInt(std::min<uint64_t>(size, uint64_t(1) << 30));
    crc = uint32_t(::crc32(crc, p, n));
    p += n;
    size -= n;
  }
  return crc;
}

// A sorted run's element: the curve key, the point's lattice position from the cloud's minimum
// (steps of the quantisation) and its packed attributes.
struct RunRecord {
  uint32_t key;
  uint32_t q[3];
  uint32_t rgba;
  uint32_t attributes;
};
static_assert(sizeof(RunRecord) == 24);

// ---- header encoding -----------------------------------------------------------------------
// Offsets of version 1 (docs/pointlet-cache.md).
namespace field {
constexpr size_t magic = 0, version = 8, header_bytes = 12, point_count = 16, pointlet_count = 24,
                 pointlet_points = 32, requested = 40, order = 48, flags = 52, scale = 56,
                 bounds = 80, enu_origin = 128, points_offset = 152, table_offset = 160,
                 file_size = 168, table_crc = 176, source_count = 180, elevation_range = 184,
                 intensity_range = 200, sources = 216, header_crc = kPointletHeaderBytes - 4;
}

template <typename T>
void put(std::vector<uint8_t>& b, size_t at, const T& v) {
  std::memcpy(b.data() + at, &v, sizeof(T));
}
template <typename T>
T get(const uint8_t* b, size_t at) {
  T v;
  std::memcpy(&v, b + at, sizeof(T));
  return v;
}

std::vector<uint8_t> encode_header(const PointletCacheInfo& info, uint32_t table_crc) {
  std::vector<uint8_t> b(kPointletHeaderBytes, 0);
  std::memcpy(b.data() + field::magic, kMagic, 8);
  put(b, field::version, info.version);
  put(b, field::header_bytes, uint32_t(kPointletHeaderBytes));
  put(b, field::point_count, info.point_count);
  put(b, field::pointlet_count, info.pointlet_count);
  put(b, field::pointlet_points, info.pointlet_points);
  put(b, field::requested, info.requested_pointlets);
  put(b, field::order, uint32_t(info.order == SpatialOrder::Morton ? 1 : 2));
  const CloudAttributes& a = info.attributes;
  uint32_t flags = (a.has_rgb ? 1u : 0u) | (a.has_intensity ? 2u : 0u) |
                   (a.has_classification ? 4u : 0u) | (a.has_returns ? 8u : 0u) |
                   (info.geographic ? 16u : 0u);
  put(b, field::flags, flags);
  for (int i = 0; i < 3; ++i) {
    put(b, field::scale + 8 * i, info.scale[i]);
    put(b, field::bounds + 8 * i, info.source_bounds.min[i]);
    put(b, field::bounds + 24 + 8 * i, info.source_bounds.max[i]);
    put(b, field::enu_origin + 8 * i, info.enu_origin[i]);
  }
  put(b, field::points_offset, info.points_offset);
  put(b, field::table_offset, info.table_offset);
  put(b, field::file_size, info.file_size);
  put(b, field::table_crc, table_crc);
  put(b, field::source_count, uint32_t(info.sources.size()));
  put(b, field::elevation_range, a.elevation_percentiles.x);
  put(b, field::elevation_range + 8, a.elevation_percentiles.y);
  put(b, field::intensity_range, a.intensity_percentiles.x);
  put(b, field::intensity_range + 8, a.intensity_percentiles.y);
  size_t at = field::sources;
  for (const PointletSource& s : info.sources) {
    const size_t need = 8 + 8 + 8 + 2 + s.path.size();
    if (at + need > field::header_crc)
      fail("pointlet cache: the sources' names do not fit the header ({} bytes)",
           kPointletHeaderBytes);
    put(b, at, s.size);
    put(b, at + 8, s.mtime_ns);
    put(b, at + 16, s.points);
    put(b, at + 24, uint16_t(s.path.size()));
    std::memcpy(b.data() + at + 26, s.path.data(), s.path.size());
    at += need;
  }
  put(b, field::header_crc, crc32_of(b.data(), field::header_crc));
  return b;
}

PointletSource stamp(const fs::path& path, uint64_t points) {
  struct stat st {};
  const fs::path abs = fs::absolute(path);
  if (::stat(abs.c_str(), &st) != 0)
    fail("{}: cannot stat: {}", path.string(), std::strerror(errno));
  PointletSource s;
  s.path = abs.string();
  s.size = uint64_t(st.st_size);
  s.mtime_ns = int64_t(st.st_mtim.tv_sec) * 1'000'000'000 + st.st_mtim.tv_nsec;
  s.points = points;
  return s;
}

uint32_t grid_key(const uint32_t q[3], const double cell_inverse, SpatialOrder order) {
  uint32_t c[3];
  for (int a = 0; a < 3; ++a)
    c[a] = std::min<uint32_t>(uint32_t(double(q[a]) * cell_inverse), (1u << kGridBits) - 1);
  const uint32_t morton = uint32_t(morton_key(c[0], c[1], c[2]));
  return order == SpatialOrder::Hilbert ? hilbert_from_morton(morton) : morton;
}

// Stable: equal keys keep their input order, so the cache does not depend on how the input
// was cut into runs.
void sort_run(std::vector<RunRecord>& run, ThreadPool& pool) {
  auto less = [](const RunRecord& a, const RunRecord& b) { return a.key < b.key; };
  const size_t parts = std::max<size_t>(1, std::min<size_t>(pool.size(), run.size() / 65536));
  std::vector<size_t> bounds(parts + 1);
  for (size_t i = 0; i <= parts; ++i) bounds[i] = run.size() * i / parts;
  pool.parallel_for(parts, 1, [&](size_t begin, size_t end) {
    for (size_t p = begin; p < end; ++p)
      std::stable_sort(run.begin() + ptrdiff_t(bounds[p]), run.begin() + ptrdiff_t(bounds[p + 1]),
                       less);
  });
  // Pairs of sorted parts merge in parallel, level by level (only the last merge is alone).
  for (size_t width = 1; width < parts; width *= 2) {
    const size_t pairs = (parts + 2 * width - 1) / (2 * width);
    pool.parallel_for(pairs, 1, [&](size_t begin, size_t end) {
      for (size_t q = begin; q < end; ++q) {
        const size_t p = q * 2 * width;
        if (p + width >= parts) continue;
        std::inplace_merge(run.begin() + ptrdiff_t(bounds[p]),
                           run.begin() + ptrdiff_t(bounds[p + width]),
                           run.begin() + ptrdiff_t(bounds[std::min(parts, p + 2 * width)]), less);
      }
    });
  }
}

// Run files on disk, removed with the builder.
struct RunFiles {
  std::vector<fs::path> paths;
  ~RunFiles() {
    std::error_code ec;
    for (const auto& p : paths) fs::remove(p, ec);
  }
};

void write_run(const fs::path& path, const std::vector<RunRecord>& run) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(run.data()),
            std::streamsize(run.size() * sizeof(RunRecord)));
  out.close();
  if (!out) fail("{}: cannot write a sort run (disk full?)", path.string());
}

// Buffered sequential reader of one run file.
class RunReader {
 public:
  RunReader(const fs::path& path, size_t buffer_records)
      : in_(path, std::ios::binary), buffer_(buffer_records) {
    if (!in_) fail("{}: cannot reopen a sort run", path.string());
    path_ = path.string();
    refill();
  }
  bool done() const { return pos_ >= size_; }
  const RunRecord& front() const { return buffer_[pos_]; }
  void pop() {
    if (++pos_ >= size_) refill();
  }

 private:
  void refill() {
    in_.read(reinterpret_cast<char*>(buffer_.data()),
             std::streamsize(buffer_.size() * sizeof(RunRecord)));
    const auto got = size_t(in_.gcount());
    if (got % sizeof(RunRecord)) fail("{}: a sort run was cut short", path_);
    size_ = got / sizeof(RunRecord);
    pos_ = 0;
  }
  std::ifstream in_;
  std::string path_;
  std::vector<RunRecord> buffer_;
  size_t size_ = 0, pos_ = 0;
};

// Cuts the sorted stream into pointlets: shuffles each (a prefix is then a uniform subsample),
// computes its box and writes its records relative to the box. Records are gathered in blocks
// of whole pointlets, which are encoded on every core and then written in order.
class PointletWriter {
 public:
  PointletWriter(std::ofstream& out, const PointletCacheInfo& info, const glm::dvec3& origin,
                 ThreadPool& pool, uint64_t block_bytes)
      : out_(out), info_(info), origin_(origin), pool_(pool) {
    // RunRecord in, PointletRecord out: 44 bytes a point while a block is encoded.
    const uint64_t k = info.pointlet_points;
    const uint64_t pointlets = std::clamp<uint64_t>(block_bytes / 44 / k, 1, (1u << 22) / k + 1);
    block_records_ = pointlets * k;
    pending_.reserve(std::min<uint64_t>(block_records_, info.point_count));
  }
  void add(const RunRecord& r) {
    pending_.push_back(r);
    if (pending_.size() == block_records_) write_block();
  }
  void flush() { write_block(); }

 private:
  void write_block() {
    if (pending_.empty()) return;
    const uint64_t k = info_.pointlet_points;
    const size_t base = table.size(), count = (pending_.size() + k - 1) / k;
    table.resize(base + count);
    records_.resize(pending_.size());
    pool_.parallel_for(count, 8, [&](size_t begin, size_t end) {
      for (size_t p = begin; p < end; ++p) encode(p, base + p);
    });
    const uint64_t bytes = records_.size() * sizeof(PointletRecord);
    out_.write(reinterpret_cast<const char*>(records_.data()), std::streamsize(bytes));
    written_ += records_.size();
    pending_.clear();
  }
  // Pointlet `index` of the cache, the `p`th of the block.
  void encode(size_t p, size_t index) {
    const uint64_t k = info_.pointlet_points;
    const size_t first = p * k, n = std::min<size_t>(k, pending_.size() - first);
    RunRecord* in = pending_.data() + first;
    // Deterministic per pointlet: the same input gives the same cache.
    std::mt19937_64 rng(0x9e3779b97f4a7c15ull * (index + 1));
    std::shuffle(in, in + n, rng);
    uint32_t lo[3] = {UINT32_MAX, UINT32_MAX, UINT32_MAX}, hi[3] = {0, 0, 0};
    for (size_t i = 0; i < n; ++i)
      for (int a = 0; a < 3; ++a) {
        lo[a] = std::min(lo[a], in[i].q[a]);
        hi[a] = std::max(hi[a], in[i].q[a]);
      }
    PointletRecord* out = records_.data() + first;
    for (size_t i = 0; i < n; ++i) {
      const RunRecord& r = in[i];
      out[i] = {{r.q[0] - lo[0], r.q[1] - lo[1], r.q[2] - lo[2]}, r.rgba, r.attributes};
    }
    PointletEntry& e = table[index];
    for (int a = 0; a < 3; ++a) {
      e.min[a] = origin_[a] + double(lo[a]) * info_.scale[a];
      // The same arithmetic as PointletCache::position, so every point lies inside the box.
      e.max[a] = e.min[a] + double(hi[a] - lo[a]) * info_.scale[a];
    }
    e.first = written_ + first;
    e.count = uint32_t(n);
    e.crc = crc32_of(out, n * sizeof(PointletRecord));
  }

 public:
  std::vector<PointletEntry> table;

 private:
  std::ofstream& out_;
  const PointletCacheInfo& info_;
  glm::dvec3 origin_;
  ThreadPool& pool_;
  uint64_t block_records_ = 1;
  std::vector<RunRecord> pending_;
  std::vector<PointletRecord> records_;
  uint64_t written_ = 0;
};

uint64_t fnv1a(std::string_view s, uint64_t h = 1469598103934665603ull) {
  for (unsigned char c : s) h = (h ^ c) * 1099511628211ull;
  return h;
}

}  // namespace

uint64_t pointlet_size(uint64_t points, uint64_t pointlets) {
  if (pointlets == 0 || points <= pointlets) return 1;
  return std::bit_floor(points / pointlets);  // 2^floor(log2(n / m)) for integer n / m
}

PointletBuildStats build_pointlet_cache(const std::vector<fs::path>& sources,
                                        const fs::path& cache_path,
                                        const PointletBuildOptions& options) {
  const auto start = Clock::now();
  if (sources.empty()) fail("pointlet cache: no input");
  if (sources.size() > kMaxSources)
    fail("pointlet cache: {} inputs (at most {})", sources.size(), kMaxSources);
  PointletBuildStats stats;
  PointletCacheInfo info;
  info.requested_pointlets = std::max<uint64_t>(1, options.pointlets);
  info.order = options.order == SpatialOrder::Morton ? SpatialOrder::Morton : SpatialOrder::Hilbert;

  // Headers: counts, bounds, scales (the finest of the inputs keeps every input's precision).
  std::vector<io::LasHeader> headers;
  Aabb box;
  glm::dvec3 scale(std::numeric_limits<double>::infinity());
  for (const auto& path : sources) {
    io::LasReader reader(path);
    headers.push_back(reader.header());
    const io::LasHeader& h = headers.back();
    // Lon/lat is turned into metres below: "degrees" that are not would make nonsense.
    if (const std::string problem = io::geographic_bounds_problem(h); !problem.empty())
      fail("{}", problem);
    if (headers.size() > 1 && h.crs.geographic != headers.front().crs.geographic)
      fail("{}: {} coordinates, but {} has {}: one cache holds one kind", path.string(),
           h.crs.geographic ? "lon/lat" : "projected", sources.front().string(),
           headers.front().crs.geographic ? "lon/lat" : "projected");
    info.point_count += h.point_count;
    if (h.point_count > 0) {
      box.extend(h.min);
      box.extend(h.max);
    }
    for (int a = 0; a < 3; ++a) scale[a] = std::min(scale[a], h.scale[a]);
    info.sources.push_back(stamp(path, h.point_count));
    CloudAttributes& at = info.attributes;
    const bool first = headers.size() == 1;
    at.has_rgb = (first || at.has_rgb) && h.has_rgb;
    at.has_intensity = true;
    at.has_classification = true;
    at.has_returns = true;
  }
  if (info.point_count == 0) fail("{}: the input holds no points", sources.front().string());
  // Lon/lat inputs are stored in metres of a local east-north-up frame at the centre of their
  // bounds (as the in-memory path draws them): the bounds are those of the frame's image of
  // the lon/lat box, sampled densely and widened by a hundredth for the curvature between
  // samples; the step is the input's finest, in metres along the meridian.
  std::optional<geo::LocalEnu> enu;
  if (headers.front().crs.geographic) {
    info.geographic = true;
    info.enu_origin = glm::dvec3(box.center().x, box.center().y, 0.0);
    enu.emplace(info.enu_origin);
    Aabb metric;
    constexpr int kSamples = 8;
    for (int i = 0; i <= kSamples; ++i)
      for (int j = 0; j <= kSamples; ++j)
        for (int k = 0; k <= 1; ++k) {
          const glm::dvec3 t(double(i) / kSamples, double(j) / kSamples, double(k));
          metric.extend(enu->from_geodetic(box.min + t * box.size()));
        }
    const glm::dvec3 widen = metric.size() * 0.01 + glm::dvec3(1.0);
    box = {metric.min - widen, metric.max + widen};
    const double metres_per_degree = geo::kWgs84A * M_PI / 180.0;
    const double xy = std::min(scale.x, scale.y) * metres_per_degree;
    scale = glm::dvec3(xy, xy, scale.z);
  }
  // Headers' bounds are a hint: keep a margin for writers that round them, and make sure every
  // lattice offset from the minimum fits 31 bits (coarser steps only for huge extents).
  const glm::dvec3 margin = glm::max(box.size() * 1e-3, scale * 16.0);
  const glm::dvec3 origin = box.min - margin;
  const glm::dvec3 extent = box.size() + 2.0 * margin;
  for (int a = 0; a < 3; ++a) {
    if (!(scale[a] > 0) || !std::isfinite(scale[a])) scale[a] = 0.001;
    scale[a] = std::max(scale[a], extent[a] / double(1u << 31));
  }
  info.scale = scale;
  const double lattice_extent =
      std::max({extent.x / scale.x, extent.y / scale.y, extent.z / scale.z, 1.0});
  const double cell_inverse = double(1u << kGridBits) / lattice_extent;
  info.pointlet_points = pointlet_size(info.point_count, info.requested_pointlets);

  ThreadPool pool(options.threads ? options.threads
                                  : std::max(1u, std::thread::hardware_concurrency()));
  // A run takes two thirds of the budget: the stable sort's merges borrow up to half a run.
  const uint64_t run_capacity =
      std::max<uint64_t>(1 << 16, options.memory_budget / 3 * 2 / sizeof(RunRecord));
  const fs::path temp_dir = options.temp_dir.empty()
                                ? (cache_path.has_parent_path() ? cache_path.parent_path() : ".")
                                : options.temp_dir;
  RunFiles runs;
  std::vector<RunRecord> run;
  run.reserve(std::min<uint64_t>(run_capacity, info.point_count));
  std::vector<double> elevation, intensity;
  const uint64_t sample_stride = std::max<uint64_t>(1, info.point_count / (1 << 20));
  uint64_t seen = 0;

  auto finish_run = [&] {
    const auto t = Clock::now();
    sort_run(run, pool);
    stats.sort_seconds += since(t);
    stats.peak_run_bytes = std::max<uint64_t>(stats.peak_run_bytes, run.size() * sizeof(RunRecord));
  };
  auto spill = [&] {
    finish_run();
    const auto t = Clock::now();
    fs::path path =
        temp_dir / (cache_path.filename().string() + ".run-" + std::to_string(::getpid()) + "-" +
                    std::to_string(runs.paths.size()));
    runs.paths.push_back(path);
    write_run(path, run);
    stats.write_seconds += since(t);
    run.clear();
  };

  // The input in windows of at most one run; a window is read by every core, each thread with
  // its own reader seeked to a slice of a source (whole LAZ chunks, so each decodes on its own),
  // storing the records at their place in the run: the run is what a sequential read makes.
  struct Slice {
    size_t source = 0;
    uint64_t first = 0, count = 0, at = 0;  // points of the source; index in the run
  };
  struct Samples {
    std::vector<double> elevation, intensity;
  };
  {
    Progress progress("sorting into pointlets", info.point_count);
    const uint64_t threads = pool.size();
    size_t f = 0;
    uint64_t local = 0;  // next point of source f
    while (seen < info.point_count) {
      const uint64_t window = std::min<uint64_t>(run_capacity, info.point_count - seen);
      std::vector<Slice> slices;
      for (uint64_t filled = 0; filled < window;) {
        while (f < sources.size() && local == headers[f].point_count) {
          ++f;
          local = 0;
        }
        if (f == sources.size()) fail("pointlet cache: the inputs hold fewer points than counted");
        const uint64_t take = std::min(window - filled, headers[f].point_count - local);
        const uint64_t chunk =
            headers[f].compressed ? std::max<uint64_t>(1, headers[f].laz_chunk_points) : 1;
        const uint64_t parts = std::clamp<uint64_t>(take / 65536, 1, threads * 2);
        uint64_t step = (take + parts - 1) / parts;
        step = (step + chunk - 1) / chunk * chunk;
        for (uint64_t s = 0; s < take; s += step)
          slices.push_back({f, local + s, std::min(step, take - s), filled + s});
        filled += take;
        local += take;
      }
      const auto t = Clock::now();
      run.resize(window);
      std::vector<Samples> samples(slices.size());
      pool.parallel_for(slices.size(), 1, [&](size_t begin, size_t end) {
        for (size_t k = begin; k < end; ++k) {
          const Slice& sl = slices[k];
          io::LasReader reader(sources[sl.source]);
          reader.seek(sl.first);
          const int rgb_bits = reader.header().rgb_bits;
          io::PointBatch batch;
          uint64_t done = 0;
          while (done < sl.count) {
            batch.clear();
            const size_t n =
                reader.read(batch, size_t(std::min<uint64_t>(1 << 16, sl.count - done)));
            if (n == 0)
              fail("{}: the header says {} points, the file holds {}", sources[sl.source].string(),
                   headers[sl.source].point_count, sl.first + done);
            if (enu)
              for (auto& p : batch.positions) p = enu->from_geodetic(p);
            for (size_t i = 0; i < n; ++i) {
              RunRecord& r = run[sl.at + done + i];
              const glm::dvec3& p = batch.positions[i];
              for (int a = 0; a < 3; ++a) {
                const double steps = std::nearbyint((p[a] - origin[a]) / scale[a]);
                if (!(steps >= 0 && steps < double(1u << 31)))
                  fail("{}: point {} lies outside the header's bounds ({}, {}, {})",
                       sources[sl.source].string(), sl.first + done + i, p.x, p.y, p.z);
                r.q[a] = uint32_t(steps);
              }
              r.key = grid_key(r.q, cell_inverse, info.order);
              r.rgba = batch_rgba(batch, i, rgb_bits);
              r.attributes = batch_attributes(batch, i);
              if ((seen + sl.at + done + i) % sample_stride == 0) {
                samples[k].elevation.push_back(p.z);
                samples[k].intensity.push_back(
                    batch.intensity.empty() ? 0.0 : double(batch.intensity[i]));
              }
            }
            done += n;
          }
        }
      });
      for (Samples& s : samples) {
        elevation.insert(elevation.end(), s.elevation.begin(), s.elevation.end());
        intensity.insert(intensity.end(), s.intensity.begin(), s.intensity.end());
      }
      stats.read_seconds += since(t);
      seen += window;
      progress.advance(window);
      if (seen < info.point_count) spill();
    }
  }
  info.attributes.elevation_percentiles = percentile_range(std::move(elevation), {}, 0.02, 0.98);
  info.attributes.intensity_percentiles = percentile_range(std::move(intensity), {}, 0.02, 0.98);

  // The cache, written under a temporary name: the points, the table, then the header.
  AtomicFile file(cache_path);
  std::ofstream out(file.temp_path(), std::ios::binary | std::ios::trunc);
  if (!out) fail("{}: cannot write", cache_path.string());
  out.write(std::string(kPointletHeaderBytes, '\0').data(), std::streamsize(kPointletHeaderBytes));
  PointletWriter writer(out, info, origin, pool,
                        std::max<uint64_t>(options.memory_budget / 4, 1 << 20));
  const auto write_start = Clock::now();
  if (runs.paths.empty()) {
    finish_run();
    for (const RunRecord& r : run) writer.add(r);
  } else {
    if (!run.empty()) spill();
    std::vector<RunRecord>().swap(run);
    // k-way merge; ties go to the earlier run, which holds the earlier input points.
    const size_t buffer = std::max<size_t>(4096, run_capacity / (runs.paths.size() + 1));
    std::vector<std::unique_ptr<RunReader>> readers;
    for (const auto& p : runs.paths) readers.push_back(std::make_unique<RunReader>(p, buffer));
    using Head = std::pair<uint32_t, size_t>;  // key, run
    std::priority_queue<Head, std::vector<Head>, std::greater<>> heads;
    for (size_t i = 0; i < readers.size(); ++i)
      if (!readers[i]->done()) heads.push({readers[i]->front().key, i});
    Progress progress("writing pointlets", info.point_count);
    uint64_t merged = 0;
    while (!heads.empty()) {
      const size_t i = heads.top().second;
      heads.pop();
      writer.add(readers[i]->front());
      readers[i]->pop();
      if (!readers[i]->done()) heads.push({readers[i]->front().key, i});
      if (++merged % (1 << 20) == 0) progress.set(merged);
    }
  }
  writer.flush();
  stats.write_seconds += since(write_start);
  info.pointlet_count = writer.table.size();
  info.points_offset = kPointletHeaderBytes;
  info.table_offset = kPointletHeaderBytes + info.point_count * sizeof(PointletRecord);
  info.file_size = info.table_offset + info.pointlet_count * sizeof(PointletEntry);
  info.source_bounds = {};
  for (const PointletEntry& e : writer.table) {
    info.source_bounds.extend(glm::dvec3(e.min[0], e.min[1], e.min[2]));
    info.source_bounds.extend(glm::dvec3(e.max[0], e.max[1], e.max[2]));
  }
  const uint64_t table_bytes = writer.table.size() * sizeof(PointletEntry);
  out.write(reinterpret_cast<const char*>(writer.table.data()), std::streamsize(table_bytes));
  const std::vector<uint8_t> header =
      encode_header(info, crc32_of(writer.table.data(), table_bytes));
  out.seekp(0);
  out.write(reinterpret_cast<const char*>(header.data()), std::streamsize(header.size()));
  out.close();
  if (!out) fail("{}: cannot write (disk full?)", cache_path.string());
  file.commit();

  stats.points = info.point_count;
  stats.pointlets = info.pointlet_count;
  stats.pointlet_points = info.pointlet_points;
  stats.runs = std::max<uint64_t>(1, runs.paths.size());
  stats.seconds = since(start);
  return stats;
}

// ---- reading --------------------------------------------------------------------------------

struct PointletCache::Storage {
  int fd = -1;
  std::vector<uint8_t> bytes;  // from_memory
  uint64_t size = 0;
  ~Storage() {
    if (fd >= 0) ::close(fd);
  }
  void read(const std::string& name, uint64_t offset, void* dst, uint64_t n) const {
    if (offset > size || n > size - offset)
      fail("{}: the cache is cut short (reading {} bytes at {} of {})", name, n, offset, size);
    if (fd < 0) {
      std::memcpy(dst, bytes.data() + offset, n);
      return;
    }
    auto* out = static_cast<uint8_t*>(dst);
    while (n > 0) {
      const ssize_t got = ::pread(fd, out, n, off_t(offset));
      if (got < 0 && errno == EINTR) continue;
      if (got <= 0)
        fail("{}: read failed at {}: {}", name, offset,
             got < 0 ? std::strerror(errno) : "end of file");
      out += got;
      offset += uint64_t(got);
      n -= uint64_t(got);
    }
  }
};

PointletCache::PointletCache(PointletCache&&) noexcept = default;
PointletCache& PointletCache::operator=(PointletCache&&) noexcept = default;
PointletCache::~PointletCache() = default;

PointletCache PointletCache::open(const fs::path& path) {
  PointletCache c;
  c.name_ = path.string();
  c.storage_ = std::make_unique<Storage>();
  c.storage_->fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (c.storage_->fd < 0) fail("{}: cannot open: {}", c.name_, std::strerror(errno));
  struct stat st {};
  if (::fstat(c.storage_->fd, &st) != 0) fail("{}: cannot stat: {}", c.name_, std::strerror(errno));
  c.storage_->size = uint64_t(st.st_size);
  c.load();
  return c;
}

PointletCache PointletCache::from_memory(std::vector<uint8_t> bytes, std::string name) {
  PointletCache c;
  c.name_ = std::move(name);
  c.storage_ = std::make_unique<Storage>();
  c.storage_->size = bytes.size();
  c.storage_->bytes = std::move(bytes);
  c.load();
  return c;
}

void PointletCache::load() {
  const std::string& n = name_;
  if (storage_->size < kPointletHeaderBytes)
    fail("{}: not a pointlet cache ({} bytes, shorter than its header)", n, storage_->size);
  std::vector<uint8_t> h(kPointletHeaderBytes);
  storage_->read(n, 0, h.data(), h.size());
  if (std::memcmp(h.data(), kMagic, 8) != 0) fail("{}: not a pointlet cache (bad magic)", n);
  PointletCacheInfo& i = info_;
  i.version = get<uint32_t>(h.data(), field::version);
  if (i.version != kPointletCacheVersion)
    fail("{}: pointlet cache version {}, this build reads version {}", n, i.version,
         kPointletCacheVersion);
  if (get<uint32_t>(h.data(), field::header_crc) != crc32_of(h.data(), field::header_crc))
    fail("{}: the header's checksum does not match (corrupt cache)", n);
  if (get<uint32_t>(h.data(), field::header_bytes) != kPointletHeaderBytes)
    fail("{}: header size {} (expected {})", n, get<uint32_t>(h.data(), field::header_bytes),
         kPointletHeaderBytes);
  i.point_count = get<uint64_t>(h.data(), field::point_count);
  i.pointlet_count = get<uint64_t>(h.data(), field::pointlet_count);
  i.pointlet_points = get<uint64_t>(h.data(), field::pointlet_points);
  i.requested_pointlets = get<uint64_t>(h.data(), field::requested);
  const uint32_t order = get<uint32_t>(h.data(), field::order);
  if (order != 1 && order != 2) fail("{}: unknown point order {}", n, order);
  i.order = order == 1 ? SpatialOrder::Morton : SpatialOrder::Hilbert;
  const uint32_t flags = get<uint32_t>(h.data(), field::flags);
  i.attributes.has_rgb = flags & 1;
  i.attributes.has_intensity = flags & 2;
  i.attributes.has_classification = flags & 4;
  i.attributes.has_returns = flags & 8;
  i.geographic = flags & 16;
  for (int a = 0; a < 3; ++a) {
    i.scale[a] = get<double>(h.data(), field::scale + 8 * a);
    i.source_bounds.min[a] = get<double>(h.data(), field::bounds + 8 * a);
    i.source_bounds.max[a] = get<double>(h.data(), field::bounds + 24 + 8 * a);
    i.enu_origin[a] = get<double>(h.data(), field::enu_origin + 8 * a);
    if (!(i.scale[a] > 0) || !std::isfinite(i.scale[a]))
      fail("{}: invalid quantisation step {}", n, i.scale[a]);
  }
  i.attributes.elevation_percentiles = {get<double>(h.data(), field::elevation_range),
                                        get<double>(h.data(), field::elevation_range + 8)};
  i.attributes.intensity_percentiles = {get<double>(h.data(), field::intensity_range),
                                        get<double>(h.data(), field::intensity_range + 8)};
  i.points_offset = get<uint64_t>(h.data(), field::points_offset);
  i.table_offset = get<uint64_t>(h.data(), field::table_offset);
  i.file_size = get<uint64_t>(h.data(), field::file_size);
  // The layout is fixed by the counts: anything else is damage.
  if (i.point_count == 0 || i.pointlet_points == 0 ||
      i.pointlet_count != (i.point_count + i.pointlet_points - 1) / i.pointlet_points ||
      i.point_count > (uint64_t(1) << 40) || i.pointlet_count > (uint64_t(1) << 32))
    fail("{}: inconsistent counts ({} points, {} pointlets of {})", n, i.point_count,
         i.pointlet_count, i.pointlet_points);
  if (i.points_offset != kPointletHeaderBytes ||
      i.table_offset != i.points_offset + i.point_count * sizeof(PointletRecord) ||
      i.file_size != i.table_offset + i.pointlet_count * sizeof(PointletEntry))
    fail("{}: inconsistent offsets (points at {}, table at {}, {} bytes)", n, i.points_offset,
         i.table_offset, i.file_size);
  if (storage_->size != i.file_size)
    fail("{}: {} bytes, its header says {} (truncated or overwritten)", n, storage_->size,
         i.file_size);
  const uint32_t source_count = get<uint32_t>(h.data(), field::source_count);
  if (source_count > kMaxSources) fail("{}: {} sources (at most {})", n, source_count, kMaxSources);
  size_t at = field::sources;
  for (uint32_t s = 0; s < source_count; ++s) {
    if (at + 26 > field::header_crc) fail("{}: the source list overruns the header", n);
    PointletSource src;
    src.size = get<uint64_t>(h.data(), at);
    src.mtime_ns = get<int64_t>(h.data(), at + 8);
    src.points = get<uint64_t>(h.data(), at + 16);
    const uint16_t len = get<uint16_t>(h.data(), at + 24);
    if (at + 26 + len > field::header_crc) fail("{}: the source list overruns the header", n);
    src.path.assign(reinterpret_cast<const char*>(h.data() + at + 26), len);
    i.sources.push_back(std::move(src));
    at += 26 + len;
  }
  table_.resize(i.pointlet_count);
  storage_->read(n, i.table_offset, table_.data(), table_.size() * sizeof(PointletEntry));
  if (crc32_of(table_.data(), table_.size() * sizeof(PointletEntry)) !=
      get<uint32_t>(h.data(), field::table_crc))
    fail("{}: the pointlet table's checksum does not match (corrupt cache)", n);
  uint64_t first = 0;
  for (size_t p = 0; p < table_.size(); ++p) {
    const PointletEntry& e = table_[p];
    const bool last = p + 1 == table_.size();
    if (e.first != first || e.count == 0 || e.count > i.pointlet_points ||
        (!last && e.count != i.pointlet_points))
      fail("{}: pointlet {} has {} points from {} (expected {} from {})", n, p, e.count, e.first,
           i.pointlet_points, first);
    for (int a = 0; a < 3; ++a)
      if (!(e.min[a] <= e.max[a]) || !std::isfinite(e.min[a]) || !std::isfinite(e.max[a]))
        fail("{}: pointlet {} has an invalid box", n, p);
    first += e.count;
  }
  if (first != i.point_count)
    fail("{}: the pointlets hold {} points, the header says {}", n, first, i.point_count);
}

void PointletCache::read(uint32_t index, uint32_t first, uint32_t count,
                         std::vector<PointletRecord>& out) const {
  if (index >= table_.size()) fail("{}: no pointlet {}", name_, index);
  const PointletEntry& e = table_[index];
  if (first > e.count || count > e.count - first)
    fail("{}: pointlet {} has {} points, not {} from {}", name_, index, e.count, count, first);
  const size_t at = out.size();
  out.resize(at + count);
  storage_->read(name_, info_.points_offset + (e.first + first) * sizeof(PointletRecord),
                 out.data() + at, uint64_t(count) * sizeof(PointletRecord));
}

std::vector<PointletRecord> PointletCache::read_verified(uint32_t index) const {
  std::vector<PointletRecord> out;
  read(index, 0, index < table_.size() ? table_[index].count : 0, out);
  if (crc32_of(out.data(), out.size() * sizeof(PointletRecord)) != table_[index].crc)
    fail("{}: pointlet {}'s checksum does not match (corrupt cache)", name_, index);
  return out;
}

glm::dvec3 PointletCache::position(const PointletEntry& p, const PointletRecord& r) const {
  return {p.min[0] + double(r.q[0]) * info_.scale.x, p.min[1] + double(r.q[1]) * info_.scale.y,
          p.min[2] + double(r.q[2]) * info_.scale.z};
}

bool PointletCache::matches(const std::vector<fs::path>& sources,
                            const PointletBuildOptions& options) const {
  if (info_.requested_pointlets != std::max<uint64_t>(1, options.pointlets)) return false;
  if ((options.order == SpatialOrder::Morton) != (info_.order == SpatialOrder::Morton))
    return false;
  if (sources.size() != info_.sources.size()) return false;
  for (size_t i = 0; i < sources.size(); ++i) {
    PointletSource now;
    try {
      now = stamp(sources[i], 0);
    } catch (const Error&) {
      return false;  // gone: rebuilding says why
    }
    const PointletSource& s = info_.sources[i];
    if (s.path != now.path || s.size != now.size || s.mtime_ns != now.mtime_ns) return false;
  }
  return true;
}

fs::path pointlet_cache_path(const std::vector<fs::path>& sources, const fs::path& cache_dir,
                             const PointletBuildOptions& options) {
  if (sources.empty()) fail("pointlet cache: no input");
  uint64_t h = fnv1a("stipple-pointlets-v" + std::to_string(kPointletCacheVersion));
  for (const auto& s : sources) h = fnv1a(fs::absolute(s).string() + "\n", h);
  h = fnv1a(std::to_string(options.pointlets) +
                (options.order == SpatialOrder::Morton ? "morton" : "hilbert"),
            h);
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(h));
  const std::string name = sources.front().filename().string() + "." + hex + ".pointlets";
  fs::path dir = cache_dir;
  if (dir.empty()) {
    const fs::path beside = fs::absolute(sources.front()).parent_path();
    if (::access(beside.c_str(), W_OK) == 0) {
      dir = beside;
    } else {
      const char* xdg = std::getenv("XDG_CACHE_HOME");
      const char* home = std::getenv("HOME");
      dir = xdg && *xdg ? fs::path(xdg) / "stipple"
                        : fs::path(home && *home ? home : "/tmp") / ".cache" / "stipple";
    }
  }
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (!fs::is_directory(dir)) fail("{}: cannot create the cache folder", dir.string());
  return dir / name;
}

PointletCache open_pointlet_cache(const std::vector<fs::path>& sources, const fs::path& cache_dir,
                                  const PointletBuildOptions& options, bool* built,
                                  PointletBuildStats* stats) {
  const fs::path path = pointlet_cache_path(sources, cache_dir, options);
  if (built) *built = false;
  if (fs::exists(path)) {
    try {
      PointletCache cache = PointletCache::open(path);
      if (cache.matches(sources, options)) return cache;
      STIPPLE_INFO("{}: the sources changed since it was built; rebuilding", path.string());
    } catch (const Error& e) {
      STIPPLE_WARN("{}; rebuilding it", e.what());
    }
  }
  PointletBuildStats s = build_pointlet_cache(sources, path, options);
  if (stats) *stats = s;
  if (built) *built = true;
  return PointletCache::open(path);
}

Aabb pointlet_world_box(const PointletEntry& e) {
  // z_up_to_y_up swaps y and z and flips the new z: the corners' images are again a box.
  Aabb box;
  box.extend(z_up_to_y_up({e.min[0], e.min[1], e.min[2]}));
  box.extend(z_up_to_y_up({e.max[0], e.max[1], e.max[2]}));
  return box;
}

PointletMetrics pointlet_metrics(const std::vector<PointletEntry>& pointlets) {
  PointletMetrics m;
  if (pointlets.empty()) return m;
  double sum = 0, sum2 = 0, square = 0;
  for (const PointletEntry& e : pointlets) {
    const double w = e.max[0] - e.min[0], d = e.max[1] - e.min[1], h = e.max[2] - e.min[2];
    const double extent = std::max({w, d, h});
    m.max_extent = std::max(m.max_extent, extent);
    sum += extent;
    sum2 += extent * extent;
    const double longer = std::max(w, d);
    square += longer > 0 ? 1.0 - std::min(w, d) / longer : 0.0;
  }
  const double n = double(pointlets.size());
  m.mean_extent = sum / n;
  m.stddev_extent = std::sqrt(std::max(0.0, sum2 / n - m.mean_extent * m.mean_extent));
  m.mean_squareness = square / n;
  return m;
}

}  // namespace stipple::pc
