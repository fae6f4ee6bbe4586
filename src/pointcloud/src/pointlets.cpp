#include "stipple/pointcloud/pointlets.hpp"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <sys/vfs.h>
#include <unistd.h>
#include <zlib.h>
#include <zstd.h>

#include <algorithm>
#include <array>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <exception>
#include <functional>
#include <limits>
#include <optional>
#include <queue>
#include <random>
#include <string_view>
#include <thread>
#include <utility>

#include <fmt/format.h>

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
// A survey delivered as tiles is one cache: the header grows (in pages) to name them all.
constexpr uint64_t kMaxSources = 65536;
constexpr uint64_t kMaxHeaderBytes = uint64_t(64) << 20;

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
                 intensity_range = 200, sources = 216;
}

// The header's size: 4096 bytes, or whole pages more where the sources' names need them (its
// last 4 bytes are its CRC).
uint64_t header_bytes_for(const std::vector<PointletSource>& sources) {
  uint64_t need = field::sources + 4;
  for (const PointletSource& s : sources) need += 26 + s.path.size();
  return (need + kPointletHeaderBytes - 1) / kPointletHeaderBytes * kPointletHeaderBytes;
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
  const uint64_t header_bytes = header_bytes_for(info.sources);
  const size_t header_crc = size_t(header_bytes - 4);
  std::vector<uint8_t> b(header_bytes, 0);
  std::memcpy(b.data() + field::magic, kMagic, 8);
  put(b, field::version, info.version);
  put(b, field::header_bytes, uint32_t(header_bytes));
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
    if (s.path.size() > UINT16_MAX) fail("{}: the path is too long for a pointlet cache", s.path);
    put(b, at, s.size);
    put(b, at + 8, s.mtime_ns);
    put(b, at + 16, s.points);
    put(b, at + 24, uint16_t(s.path.size()));
    std::memcpy(b.data() + at + 26, s.path.data(), s.path.size());
    at += need;
  }
  put(b, header_crc, crc32_of(b.data(), header_crc));
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

// Keys are 3 * kGridBits = 30 bits: three passes of 10-bit digits.
constexpr uint32_t kKeyBits = 3 * kGridBits, kDigitBits = 10, kDigits = 1u << kDigitBits;
// A sorted run is indexed by the top bits of its keys, so that the merge reads the same key
// range of every run at once (a window) and sorts it in memory: 16 bits where the tables fit an
// eighth of the memory budget (8 bytes an entry per run), fewer for many runs in little memory
// (coarser windows; a prefix over a run's worth is merged through a heap).
struct PrefixBits {
  uint32_t bits = 16;
  uint32_t count() const { return 1u << bits; }
  uint32_t of(uint32_t key) const { return key >> (kKeyBits - bits); }
};
PrefixBits prefix_bits(uint64_t runs, uint64_t memory_budget) {
  PrefixBits p;
  while (p.bits > 4 && runs * (uint64_t(p.count()) + 1) * 8 > memory_budget / 8) --p.bits;
  return p;
}

// Memory for n records, not zeroed (the readers fill it on every core); seen as RunRecords or,
// once those are encoded, as PointletRecords (fewer bytes each).
struct Arena {
  std::unique_ptr<unsigned char[]> bytes;
  explicit Arena(uint64_t records) : bytes(new unsigned char[records * sizeof(RunRecord)]) {}
  RunRecord* runs() { return reinterpret_cast<RunRecord*>(bytes.get()); }
  PointletRecord* pointlets() { return reinterpret_cast<PointletRecord*>(bytes.get()); }
};

// [begin, end) of part p of n items cut into `parts`.
size_t part_begin(size_t n, size_t parts, size_t p) {
  return n * p / parts;
}

// Stable LSD radix sort by key on every core: equal keys keep their input order, so the cache
// does not depend on how the input was cut into runs or windows. Digits that every key shares
// are skipped. Returns which of `data` and `scratch` holds the sorted records.
RunRecord* radix_sort(RunRecord* data, RunRecord* scratch, size_t n, ThreadPool& pool) {
  const size_t parts = std::max<size_t>(1, std::min<size_t>(pool.size(), n / 65536));
  std::vector<std::array<uint64_t, kDigits>> counts(parts);
  RunRecord *src = data, *dst = scratch;
  for (uint32_t shift = 0; shift < kKeyBits; shift += kDigitBits) {
    pool.parallel_for(parts, 1, [&](size_t begin, size_t end) {
      for (size_t p = begin; p < end; ++p) {
        auto& c = counts[p];
        c.fill(0);
        for (size_t i = part_begin(n, parts, p), e = part_begin(n, parts, p + 1); i < e; ++i)
          ++c[(src[i].key >> shift) & (kDigits - 1)];
      }
    });
    // Where each part's records of each digit go: digit-major, then part (stable).
    uint64_t at = 0;
    bool shared = false;
    for (uint32_t d = 0; d < kDigits; ++d) {
      uint64_t total = 0;
      for (size_t p = 0; p < parts; ++p) {
        const uint64_t c = counts[p][d];
        counts[p][d] = at;
        at += c;
        total += c;
      }
      shared = shared || total == n;
    }
    if (shared) continue;  // one digit for all: this pass would not move anything
    pool.parallel_for(parts, 1, [&](size_t begin, size_t end) {
      for (size_t p = begin; p < end; ++p) {
        auto& o = counts[p];
        for (size_t i = part_begin(n, parts, p), e = part_begin(n, parts, p + 1); i < e; ++i)
          dst[o[(src[i].key >> shift) & (kDigits - 1)]++] = src[i];
      }
    });
    std::swap(src, dst);
  }
  return src;
}

// A window of the merge: its records as read, each run's part of it sorted and the parts in run
// order. merge_window writes them to `out` in key order, ties in run order (the input's), as a
// stable sort of the window would, in one pass instead of the sort's three: the window is cut
// at key prefixes into pieces of about equal size, and each core merges its pieces' parts of
// every run, taking the smallest (key, run) of the parts' heads. (1B points, 4G: the window
// sorts took about half of the sort phase's 7.4 s on the H200 machine's 16 cores.)
struct WindowPart {
  const uint64_t* starts;  // the run's prefix starts (RunFile::starts)
  uint64_t at;             // where the run's part begins in the window
};
void merge_window(const RunRecord* window, RunRecord* out, const std::vector<WindowPart>& parts,
                  const std::vector<uint64_t>& totals, uint32_t b0, uint32_t b1, uint64_t size,
                  ThreadPool& pool) {
  // Pieces of whole prefixes, about a sixteenth of a core's share each (a prefix larger than
  // that is a piece alone).
  const uint64_t target = std::max<uint64_t>(1, size / (uint64_t(pool.size()) * 16));
  std::vector<uint32_t> cuts{b0};
  uint64_t filled = 0;
  for (uint32_t b = b0; b < b1; ++b) {
    filled += totals[b];
    if (filled >= target && b + 1 < b1) {
      cuts.push_back(b + 1);
      filled = 0;
    }
  }
  cuts.push_back(b1);
  std::vector<uint64_t> piece_out(cuts.size(), 0);  // where each piece's records go
  for (size_t i = 1; i < cuts.size(); ++i) {
    piece_out[i] = piece_out[i - 1];
    for (uint32_t b = cuts[i - 1]; b < cuts[i]; ++b) piece_out[i] += totals[b];
  }
  pool.parallel_for(cuts.size() - 1, 1, [&](size_t begin, size_t end) {
    const size_t k = parts.size();
    std::vector<const RunRecord*> next(k), last(k);
    // The head of each run's part as (key << 32 | run): the smallest is the next record, ties
    // to the earlier run; an empty part is all ones, above any (30-bit) key.
    std::vector<uint64_t> heads(k);
    for (size_t piece = begin; piece < end; ++piece) {
      const uint32_t p0 = cuts[piece], p1 = cuts[piece + 1];
      for (size_t r = 0; r < k; ++r) {
        const uint64_t* st = parts[r].starts;
        next[r] = window + parts[r].at + (st[p0] - st[b0]);
        last[r] = window + parts[r].at + (st[p1] - st[b0]);
        heads[r] = next[r] < last[r] ? uint64_t(next[r]->key) << 32 | r : ~uint64_t(0);
      }
      RunRecord* o = out + piece_out[piece];
      RunRecord* const o_end = out + piece_out[piece + 1];
      while (o < o_end) {
        uint64_t m = heads[0];
        for (size_t r = 1; r < k; ++r) m = std::min(m, heads[r]);
        const uint32_t r = uint32_t(m);
        *o++ = *next[r]++;
        heads[r] = next[r] < last[r] ? uint64_t(next[r]->key) << 32 | r : ~uint64_t(0);
      }
    }
  });
}

// starts[b]: the first record of a sorted run whose key prefix is at least b (b <= count).
std::vector<uint64_t> prefix_starts(const RunRecord* run, size_t n, PrefixBits prefix,
                                    ThreadPool& pool) {
  std::vector<uint64_t> starts(prefix.count() + 1, n);
  const size_t parts = std::max<size_t>(1, std::min<size_t>(pool.size(), n / 65536));
  // Each prefix's start is set by the one record where the prefix is reached.
  pool.parallel_for(parts, 1, [&](size_t begin, size_t end) {
    for (size_t p = begin; p < end; ++p)
      for (size_t i = part_begin(n, parts, p), e = part_begin(n, parts, p + 1); i < e; ++i) {
        const uint32_t to = prefix.of(run[i].key);
        for (uint32_t b = i == 0 ? 0 : prefix.of(run[i - 1].key) + 1; b <= to; ++b) starts[b] = i;
      }
  });
  return starts;
}

// A file descriptor closed with its holder.
struct Fd {
  int fd = -1;
  Fd() = default;
  explicit Fd(int f) : fd(f) {}
  Fd(Fd&& o) noexcept : fd(std::exchange(o.fd, -1)) {}
  Fd& operator=(Fd&& o) noexcept {
    std::swap(fd, o.fd);
    return *this;
  }
  ~Fd() {
    if (fd >= 0) ::close(fd);
  }
};

void write_at(int fd, const void* data, uint64_t n, uint64_t offset, const std::string& name) {
  const auto* p = static_cast<const uint8_t*>(data);
  while (n > 0) {
    const ssize_t put = ::pwrite(fd, p, std::min<uint64_t>(n, uint64_t(1) << 30), off_t(offset));
    if (put < 0 && errno == EINTR) continue;
    if (put <= 0) fail("{}: cannot write: {} (disk full?)", name, std::strerror(errno));
    p += put;
    offset += uint64_t(put);
    n -= uint64_t(put);
  }
}

void read_at(int fd, void* data, uint64_t n, uint64_t offset, const std::string& name) {
  auto* p = static_cast<uint8_t*>(data);
  while (n > 0) {
    const ssize_t got = ::pread(fd, p, std::min<uint64_t>(n, uint64_t(1) << 30), off_t(offset));
    if (got < 0 && errno == EINTR) continue;
    if (got <= 0)
      fail("{}: cannot read back a sort run: {}", name,
           got < 0 ? std::strerror(errno) : "cut short");
    p += got;
    offset += uint64_t(got);
    n -= uint64_t(got);
  }
}

// Large sequential writes from every core: the kernel's copy into the page cache is most of a
// write's cost, and it runs on the writing thread.
constexpr uint64_t kWritePiece = uint64_t(8) << 20;
void write_parallel(int fd, const void* data, uint64_t n, uint64_t offset, const std::string& name,
                    ThreadPool& pool) {
  const auto* p = static_cast<const uint8_t*>(data);
  pool.parallel_for(size_t((n + kWritePiece - 1) / kWritePiece), 1, [&](size_t begin, size_t end) {
    for (size_t i = begin; i < end; ++i) {
      const uint64_t at = i * kWritePiece;
      write_at(fd, p + at, std::min(kWritePiece, n - at), offset + at, name);
    }
  });
}

// The cache's pointlets go through a shared mapping of their range, copied on every write
// thread: buffered pwrite()s to one file take its inode lock, so they copy one at a time
// whatever the threads (this 2-core machine, tmpfs: one thread 2.15 GB/s, two 2.04 GB/s;
// through a mapping 1.31 and 2.40 GB/s), and the 1B-point build waited 8-9 s for the cache's
// writes on the 16-core machine. The range's pages are allocated first (fallocate), so a full
// disk is an error here and never a SIGBUS in a copy; that holds on ext4, XFS and tmpfs, whose
// fallocate reserves the blocks a mapped write later dirties. Elsewhere (btrfs and ZFS reserve
// again at the page's first write, and a full disk would be a SIGBUS), where the file system has
// no fallocate or mapping, or with STIPPLE_CACHE_WRITE=pwrite (benches), the writes are pwrite()s.
// Decided once a cache file, by its file system.
bool mapped_writes_suit(int fd) {
  const char* v = std::getenv("STIPPLE_CACHE_WRITE");
  if (v && std::string_view(v) == "pwrite") return false;
  struct statfs fs {};
  if (::fstatfs(fd, &fs) != 0) return false;
  constexpr decltype(fs.f_type) kExt4 = 0xEF53, kXfs = 0x58465342, kTmpfs = 0x01021994;
  return fs.f_type == kExt4 || fs.f_type == kXfs || fs.f_type == kTmpfs;
}

bool write_mapped(int fd, const void* data, uint64_t n, uint64_t offset, const std::string& name,
                  ThreadPool& pool) {
  if (n == 0) return true;
  // From the first mapped page's start: a page is dirtied whole, and its part before `offset`
  // (the header's place, written last) needs its blocks too.
  const uint64_t page = uint64_t(::sysconf(_SC_PAGESIZE));
  const uint64_t first = offset / page * page;
  if (::fallocate(fd, 0, off_t(first), off_t(offset + n - first)) != 0) {
    if (errno == EOPNOTSUPP || errno == ENOSYS) return false;
    fail("{}: cannot write {} bytes: {}{}", name, n, std::strerror(errno),
         errno == ENOSPC ? " (disk full)" : "");
  }
  // A mapping a piece, unmapped once copied: the mapped pages count in the process's resident
  // set (a window's 1.8 GB mapped at once raised the peak RSS by as much).
  const auto* from = static_cast<const uint8_t*>(data);
  pool.parallel_for(size_t((n + kWritePiece - 1) / kWritePiece), 1, [&](size_t begin, size_t end) {
    for (size_t i = begin; i < end; ++i) {
      const uint64_t at = i * kWritePiece, length = std::min(kWritePiece, n - at);
      const uint64_t start = (offset + at) / page * page, mapped = offset + at + length - start;
      void* map = ::mmap(nullptr, mapped, PROT_WRITE, MAP_SHARED, fd, off_t(start));
      if (map == MAP_FAILED) {
        write_at(fd, from + at, length, offset + at, name);
        continue;
      }
      std::memcpy(static_cast<uint8_t*>(map) + (offset + at - start), from + at, length);
      ::munmap(map, mapped);
    }
  });
  return true;
}

// A positional write on threads of its own, so that the build reads the next window meanwhile:
// the writes (runs, then the cache) are the build's largest phase, and the reads of the input
// and of the runs leave the disk idle (1B points on the H100 machine: read 5.8 s, merge 7.1 s,
// write 12.7 s of 33.6 s, one after the other). One write at a time; wait() before its buffer is
// used again, and it rethrows the write's error. The destructor waits too, so a build that fails
// elsewhere never leaves a thread writing from freed memory.
class BackgroundWrite {
 public:
  BackgroundWrite(unsigned threads, PointletBuildStats& stats) : pool_(threads), stats_(stats) {}
  ~BackgroundWrite() {
    if (thread_.joinable()) thread_.join();
  }
  BackgroundWrite(const BackgroundWrite&) = delete;
  BackgroundWrite& operator=(const BackgroundWrite&) = delete;

  void start(int fd, const void* data, uint64_t n, uint64_t offset, std::string name,
             bool mapped = false) {
    start_job([fd, data, n, offset, name = std::move(name), mapped](ThreadPool& pool) {
      if (!mapped || !write_mapped(fd, data, n, offset, name, pool))
        write_parallel(fd, data, n, offset, name, pool);
    });
  }
  // Any job that writes, on the write threads (a run's blocks compress there too).
  void start_job(std::function<void(ThreadPool&)> job) {
    wait();
    thread_ = std::thread([this, job = std::move(job)] {
      const auto t = Clock::now();
      try {
        job(pool_);
      } catch (...) {
        error_ = std::current_exception();
      }
      seconds_ = since(t);
    });
  }
  void wait() {
    if (!thread_.joinable()) return;
    const auto t = Clock::now();
    thread_.join();
    stats_.write_seconds += seconds_;
    stats_.write_wait_seconds += since(t);
    if (error_) std::rethrow_exception(std::exchange(error_, nullptr));
  }

 private:
  ThreadPool pool_;
  PointletBuildStats& stats_;
  std::thread thread_;
  std::exception_ptr error_;
  double seconds_ = 0;
};

// Threads for the background writes: the reads run on every core meanwhile, and a write is the
// kernel's copies into the page cache, then the disk.
unsigned background_write_threads(const ThreadPool& pool) {
  return std::max(2u, pool.size() / 2);
}

// ---- sort runs on disk ----------------------------------------------------------------------
// A run is written in blocks of kRunBlock records, each as byte planes (byte 0 of every record,
// then byte 1, ...) compressed by zstd: sorted keys and neighbouring points share their high
// bytes, so the planes shrink about 2.5 times (generated points), and the runs are the build's
// largest I/O (1B points: 24 GB written and read back, beside the 20 GB cache). Block k lies at
// k * kRunBlockBytes in the file whatever its size, so blocks compress and write on every core
// without waiting for each other (the file is sparse between them), and a block is read alone.
constexpr uint64_t kRunBlock = 16384;
constexpr uint64_t kRunBlockBytes = kRunBlock * sizeof(RunRecord);  // whole pages
static_assert(kRunBlockBytes % 4096 == 0);
// zstd's first fast level: on a run of generated points 2.53x at 1.2 GB/s a core, against
// level 1's 2.55x at 0.86 GB/s.
constexpr int kRunLevel = -1;

// A thread's zstd contexts and buffers, made on first use and kept while the thread lives.
struct RunCodec {
  ZSTD_CCtx* compress = nullptr;
  ZSTD_DCtx* decompress = nullptr;
  std::vector<uint8_t> planes, packed;
  ~RunCodec() {
    ZSTD_freeCCtx(compress);
    ZSTD_freeDCtx(decompress);
  }
};
RunCodec& run_codec() {
  thread_local RunCodec codec;
  return codec;
}

// Records to byte planes and back, through a tile of kPlaneTile records in the cache: a byte at
// a time straight across the 24 planes (16 KB apart) measured 12 times slower.
constexpr size_t kPlaneTile = 256;
void records_to_planes(const RunRecord* records, size_t n, uint8_t* planes) {
  const auto* bytes = reinterpret_cast<const uint8_t*>(records);
  uint8_t tile[sizeof(RunRecord)][kPlaneTile];
  for (size_t s = 0; s < n; s += kPlaneTile) {
    const size_t m = std::min(kPlaneTile, n - s);
    for (size_t i = 0; i < m; ++i)
      for (size_t b = 0; b < sizeof(RunRecord); ++b)
        tile[b][i] = bytes[(s + i) * sizeof(RunRecord) + b];
    for (size_t b = 0; b < sizeof(RunRecord); ++b) std::memcpy(planes + b * n + s, tile[b], m);
  }
}

// Records [lo, hi) of a block of n records, from its planes.
void planes_to_records(const uint8_t* planes, size_t n, size_t lo, size_t hi, RunRecord* out) {
  auto* bytes = reinterpret_cast<uint8_t*>(out);
  uint8_t tile[sizeof(RunRecord)][kPlaneTile];
  for (size_t s = lo; s < hi; s += kPlaneTile) {
    const size_t m = std::min(kPlaneTile, hi - s);
    for (size_t b = 0; b < sizeof(RunRecord); ++b) std::memcpy(tile[b], planes + b * n + s, m);
    for (size_t i = 0; i < m; ++i)
      for (size_t b = 0; b < sizeof(RunRecord); ++b)
        bytes[(s - lo + i) * sizeof(RunRecord) + b] = tile[b][i];
  }
}

// Compresses a sorted run's blocks and writes each at its place, on the pool's threads; returns
// each block's bytes in the file (a block that zstd would not shrink is stored as records).
std::vector<uint32_t> write_run_blocks(int fd, const RunRecord* records, uint64_t n,
                                       const std::string& name, ThreadPool& pool) {
  const uint64_t blocks = (n + kRunBlock - 1) / kRunBlock;
  std::vector<uint32_t> sizes(blocks);
  pool.parallel_for(blocks, 1, [&](size_t begin, size_t end) {
    RunCodec& c = run_codec();
    if (!c.compress && !(c.compress = ZSTD_createCCtx()))
      fail("{}: cannot write a sort run: out of memory", name);
    for (size_t k = begin; k < end; ++k) {
      const uint64_t first = k * kRunBlock, count = std::min(kRunBlock, n - first);
      const uint64_t raw = count * sizeof(RunRecord);
      c.planes.resize(raw);
      records_to_planes(records + first, count, c.planes.data());
      c.packed.resize(ZSTD_compressBound(raw));
      const size_t got = ZSTD_compressCCtx(c.compress, c.packed.data(), c.packed.size(),
                                           c.planes.data(), raw, kRunLevel);
      const bool stored = ZSTD_isError(got) || got >= raw;
      sizes[k] = uint32_t(stored ? raw : got);
      write_at(fd, stored ? static_cast<const void*>(records + first) : c.packed.data(), sizes[k],
               k * kRunBlockBytes, name);
    }
  });
  return sizes;
}

// A sorted run on disk, its blocks' sizes and where each key prefix starts in it; removed with
// the builder.
struct RunFile {
  fs::path path;
  Fd fd;
  uint64_t count = 0;
  std::vector<uint64_t> starts;
  std::vector<uint32_t> block_bytes;  // set by the run's write
};

// Records [lo, hi) of block k of a run (indices in the block) into `out`.
void read_run_block(const RunFile& r, uint64_t k, uint64_t lo, uint64_t hi, RunRecord* out) {
  const std::string name = r.path.string();
  if (k >= r.block_bytes.size()) fail("{}: a sort run is shorter than its records", name);
  const uint64_t count = std::min(kRunBlock, r.count - k * kRunBlock);
  const uint64_t raw = count * sizeof(RunRecord);
  const uint32_t size = r.block_bytes[k];
  if (size == raw) {  // stored as records
    read_at(r.fd.fd, out, (hi - lo) * sizeof(RunRecord),
            k * kRunBlockBytes + lo * sizeof(RunRecord), name);
    return;
  }
  RunCodec& c = run_codec();
  if (!c.decompress && !(c.decompress = ZSTD_createDCtx()))
    fail("{}: cannot read back a sort run: out of memory", name);
  c.packed.resize(size);
  read_at(r.fd.fd, c.packed.data(), size, k * kRunBlockBytes, name);
  c.planes.resize(raw);
  const size_t got = ZSTD_decompressDCtx(c.decompress, c.planes.data(), raw, c.packed.data(), size);
  if (ZSTD_isError(got) || got != raw)
    fail("{}: a sort run's block {} is damaged: {}", name, k,
         ZSTD_isError(got) ? ZSTD_getErrorName(got) : "too short");
  planes_to_records(c.planes.data(), count, lo, hi, out);
}

// Records [first, first + n) of a run into `out`, block by block.
void read_run_records(const RunFile& r, uint64_t first, uint64_t n, RunRecord* out) {
  while (n > 0) {
    const uint64_t k = first / kRunBlock, lo = first % kRunBlock;
    const uint64_t take = std::min(n, kRunBlock - lo);
    read_run_block(r, k, lo, lo + take, out);
    first += take;
    n -= take;
    out += take;
  }
}

struct RunFiles {
  std::deque<RunFile> files;  // a run's write holds a reference to its RunFile
  ~RunFiles() {
    std::error_code ec;
    for (auto& f : files) {
      f.fd = Fd();
      fs::remove(f.path, ec);
    }
  }
};

// Cuts the sorted stream into pointlets: shuffles each (a prefix is then a uniform subsample),
// computes its box and writes its records relative to the box. The stream comes in pieces of
// any length; whole pointlets are encoded on every core and written at their place in the
// cache, in the background (BackgroundWrite); a pointlet cut between pieces waits in `carry_`.
class PointletWriter {
 public:
  PointletWriter(int fd, std::string name, const PointletCacheInfo& info, const glm::dvec3& origin,
                 ThreadPool& pool, PointletBuildStats& stats)
      : fd_(fd),
        name_(std::move(name)),
        info_(info),
        origin_(origin),
        pool_(pool),
        stats_(stats),
        writes_(background_write_threads(pool), stats) {}
  // The next n records of the sorted stream (shuffled in place); `out` has room for n
  // PointletRecords, and is written from in the background until wait() (or the next add).
  // `records` is free again when add returns.
  void add(RunRecord* records, size_t n, PointletRecord* out) {
    const uint64_t k = info_.pointlet_points;
    if (!carry_.empty()) {
      const size_t take = std::min<size_t>(k - carry_.size(), n);
      carry_.insert(carry_.end(), records, records + take);
      records += take;
      n -= take;
      if (carry_.size() < k) return;
      flush();
    }
    const size_t whole = n / k * k;
    if (whole > 0) emit(records, whole, out);
    carry_.assign(records + whole, records + n);
  }
  // The last pointlet, which may be shorter; then every write is done.
  void flush() {
    if (!carry_.empty()) {
      std::vector<PointletRecord> out(carry_.size());
      emit(carry_.data(), carry_.size(), out.data());
      carry_.clear();
      wait();
    }
    wait();
  }
  // The last add's write is done: its `out` may be used again.
  void wait() { writes_.wait(); }

  std::vector<PointletEntry> table;

 private:
  void emit(RunRecord* records, size_t n, PointletRecord* out) {
    writes_.wait();  // `out` may be what the last write reads
    const uint64_t k = info_.pointlet_points;
    const size_t base = table.size(), count = (n + k - 1) / k;
    table.resize(base + count);
    const auto t = Clock::now();
    const size_t grain = std::max<size_t>(1, count / (size_t(pool_.size()) * 4));
    pool_.parallel_for(count, grain, [&](size_t begin, size_t end) {
      for (size_t p = begin; p < end; ++p) encode(records, n, out, p, base + p);
    });
    stats_.encode_seconds += since(t);
    writes_.start(fd_, out, n * sizeof(PointletRecord),
                  info_.points_offset + written_ * sizeof(PointletRecord), name_, mapped_);
    written_ += n;
  }
  // Pointlet `index` of the cache, the `p`th of these n records.
  void encode(RunRecord* records, size_t total, PointletRecord* out_records, size_t p,
              size_t index) {
    const uint64_t k = info_.pointlet_points;
    const size_t first = p * k, n = std::min<size_t>(k, total - first);
    RunRecord* in = records + first;
    // Deterministic per pointlet: the same input gives the same cache.
    std::mt19937_64 rng(0x9e3779b97f4a7c15ull * (index + 1));
    std::shuffle(in, in + n, rng);
    uint32_t lo[3] = {UINT32_MAX, UINT32_MAX, UINT32_MAX}, hi[3] = {0, 0, 0};
    for (size_t i = 0; i < n; ++i)
      for (int a = 0; a < 3; ++a) {
        lo[a] = std::min(lo[a], in[i].q[a]);
        hi[a] = std::max(hi[a], in[i].q[a]);
      }
    PointletRecord* out = out_records + first;
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

  int fd_;
  std::string name_;
  const PointletCacheInfo& info_;
  glm::dvec3 origin_;
  ThreadPool& pool_;
  PointletBuildStats& stats_;
  std::vector<RunRecord> carry_;
  uint64_t written_ = 0;
  bool mapped_ = mapped_writes_suit(fd_);
  BackgroundWrite writes_;  // last: joined before the rest goes
};

// The merge of one key prefix that holds more points than a run (a dense spot, which windows
// of prefixes cannot cut): its part of every run is streamed through a heap (ties go to the
// earlier run, as in the windows' stable sort) and handed to the writer a run's worth at a time.
void merge_prefix(const RunFiles& runs, uint32_t prefix, RunRecord* block, uint64_t capacity,
                  PointletRecord* encoded, PointletWriter& writer, PointletBuildStats& stats) {
  const auto t = Clock::now();
  const double written = stats.encode_seconds + stats.write_wait_seconds;
  struct Cursor {
    const RunFile* run;
    uint64_t next, end;
    std::vector<RunRecord> buffer;
    size_t pos = 0;
  };
  auto refill = [](Cursor& c) {
    const uint64_t n = std::min<uint64_t>(1 << 16, c.end - c.next);
    c.buffer.resize(n);
    read_run_records(*c.run, c.next, n, c.buffer.data());
    c.next += n;
    c.pos = 0;
  };
  std::vector<Cursor> cursors;
  for (const RunFile& r : runs.files)
    if (r.starts[prefix] < r.starts[prefix + 1]) {
      cursors.push_back({&r, r.starts[prefix], r.starts[prefix + 1], {}, 0});
      refill(cursors.back());
    }
  using Head = std::pair<uint32_t, size_t>;  // key, cursor (in run order)
  std::priority_queue<Head, std::vector<Head>, std::greater<>> heads;
  for (size_t i = 0; i < cursors.size(); ++i) heads.push({cursors[i].buffer[0].key, i});
  uint64_t filled = 0;
  while (!heads.empty()) {
    const size_t i = heads.top().second;
    heads.pop();
    Cursor& c = cursors[i];
    block[filled++] = c.buffer[c.pos++];
    if (c.pos == c.buffer.size() && c.next < c.end) refill(c);
    if (c.pos < c.buffer.size()) heads.push({c.buffer[c.pos].key, i});
    if (filled == capacity) {
      writer.add(block, filled, encoded);
      filled = 0;
    }
  }
  if (filled > 0) writer.add(block, filled, encoded);
  stats.merge_seconds += since(t) - (stats.encode_seconds + stats.write_wait_seconds - written);
}

uint64_t fnv1a(std::string_view s, uint64_t h = 1469598103934665603ull) {
  for (unsigned char c : s) h = (h ^ c) * 1099511628211ull;
  return h;
}

}  // namespace

uint64_t pointlet_size(uint64_t points, uint64_t pointlets) {
  if (pointlets == 0 || points <= pointlets) return 1;
  return std::bit_floor(points / pointlets);  // 2^floor(log2(n / m)) for integer n / m
}

std::string describe_build_phases(const PointletBuildStats& s) {
  return fmt::format(
      "cache build: {} points in {:.2f} s ({:.2f} M points/s); read {:.2f} s, sort {:.2f} s, "
      "merge {:.2f} s{}, encode {:.2f} s, write {:.2f} s (beside the reads; {:.2f} s waited "
      "for); {} run{}{}",
      s.points, s.seconds, double(s.points) / std::max(s.seconds, 1e-9) / 1e6, s.read_seconds,
      s.sort_seconds, s.merge_seconds,
      s.run_bytes > 0 ? fmt::format(" (runs read back {:.2f} s)", s.run_read_seconds) : "",
      s.encode_seconds, s.write_seconds, s.write_wait_seconds, s.runs, s.runs == 1 ? "" : "s",
      s.run_bytes > 0 ? fmt::format(" ({:.2f} GB of records, {:.2f} GB compressed)",
                                    double(s.run_bytes) / 1e9, double(s.run_disk_bytes) / 1e9)
                      : "");
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
  info.points_offset = header_bytes_for(info.sources);

  ThreadPool pool(options.threads ? options.threads
                                  : std::max(1u, std::thread::hardware_concurrency()));
  // A run takes half of the budget: the radix sort moves it into a buffer of its size.
  const uint64_t run_capacity = std::min<uint64_t>(
      info.point_count, std::max<uint64_t>(1 << 16, options.memory_budget / 2 / sizeof(RunRecord)));
  const fs::path temp_dir = options.temp_dir.empty()
                                ? (cache_path.has_parent_path() ? cache_path.parent_path() : ".")
                                : options.temp_dir;
  RunFiles runs;
  const PrefixBits prefix =
      prefix_bits((info.point_count + run_capacity - 1) / run_capacity, options.memory_budget);
  Arena run_arena(run_capacity), scratch_arena(run_capacity);
  // The other of the two buffers: a window is read into one while the other is written out.
  auto other_of = [&](const RunRecord* p) {
    return p == run_arena.runs() ? scratch_arena.runs() : run_arena.runs();
  };
  RunRecord* run = run_arena.runs();  // where the next window is read
  // The sorted runs go to disk in the background while the next window is read.
  BackgroundWrite run_writes(background_write_threads(pool), stats);
  uint64_t run_size = 0;
  std::vector<double> elevation, intensity;
  const uint64_t sample_stride = std::max<uint64_t>(1, info.point_count / (1 << 20));
  uint64_t seen = 0;

  // Sorts the run; returns where the sorted records are and where the other buffer is.
  auto sort_run = [&] {
    run_writes.wait();  // the sort's scratch is the buffer the last run is written from
    const auto t = Clock::now();
    RunRecord* sorted = radix_sort(run, other_of(run), run_size, pool);
    stats.sort_seconds += since(t);
    stats.peak_run_bytes = std::max<uint64_t>(stats.peak_run_bytes, run_size * sizeof(RunRecord));
    return sorted;
  };
  auto spill = [&] {
    const RunRecord* sorted = sort_run();
    const auto t = Clock::now();
    RunFile f;
    f.path = temp_dir / (cache_path.filename().string() + ".run-" + std::to_string(::getpid()) +
                         "-" + std::to_string(runs.files.size()));
    f.fd = Fd(::open(f.path.c_str(), O_RDWR | O_CREAT | O_TRUNC | O_CLOEXEC, 0600));
    if (f.fd.fd < 0) fail("{}: cannot write a sort run: {}", f.path.string(), std::strerror(errno));
    runs.files.push_back(std::move(f));
    RunFile& file = runs.files.back();
    file.count = run_size;
    file.starts = prefix_starts(sorted, run_size, prefix, pool);
    stats.write_seconds += since(t);
    run_writes.start_job([&file, sorted, n = run_size](ThreadPool& writers) {
      file.block_bytes = write_run_blocks(file.fd.fd, sorted, n, file.path.string(), writers);
    });
    run_size = 0;
    run = other_of(sorted);  // the next window goes to the buffer the sort left free
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
    if (options.report) {
      options.report->total = info.point_count;
      options.report->done = 0;
      options.report->phase = 1;
    }
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
      run_size = window;
      std::vector<Samples> samples(slices.size());
      pool.parallel_for(slices.size(), 1, [&](size_t begin, size_t end) {
        for (size_t k = begin; k < end; ++k) {
          const Slice& sl = slices[k];
          io::LasReader reader(sources[sl.source], true);  // the fields the cache keeps
          reader.seek(sl.first);
          const int rgb_bits = reader.header().rgb_bits;
          const bool has_rgb = reader.header().has_rgb;
          // A few thousand points at a time, so that the records and their drawn fields stay
          // in the core's cache on their way into the run.
          std::vector<io::DrawnPoint> drawn(4096);
          uint64_t done = 0;
          // Every sample_stride-th point of the input is sampled for the colour ramps: the
          // next one's index in this slice (no division per point).
          const uint64_t global = seen + sl.at;
          uint64_t next_sample =
              (global + sample_stride - 1) / sample_stride * sample_stride - global;
          while (done < sl.count) {
            // A reader elsewhere sees the read advance (and may end it) batch by batch.
            if (options.report && options.report->cancel)
              fail("{}: the cache build was cancelled", cache_path.string());
            const size_t n = reader.read_drawn(
                std::span(drawn).first(size_t(std::min<uint64_t>(drawn.size(), sl.count - done))));
            if (n == 0)
              fail("{}: the header says {} points, the file holds {}", sources[sl.source].string(),
                   headers[sl.source].point_count, sl.first + done);
            for (size_t i = 0; i < n; ++i) {
              RunRecord& r = run[sl.at + done + i];
              const io::DrawnPoint& d = drawn[i];
              const glm::dvec3 p = enu ? enu->from_geodetic(d.position) : d.position;
              for (int a = 0; a < 3; ++a) {
                const double steps = std::nearbyint((p[a] - origin[a]) / scale[a]);
                if (!(steps >= 0 && steps < double(1u << 31)))
                  fail("{}: point {} lies outside the header's bounds ({}, {}, {})",
                       sources[sl.source].string(), sl.first + done + i, p.x, p.y, p.z);
                r.q[a] = uint32_t(steps);
              }
              r.key = grid_key(r.q, cell_inverse, info.order);
              r.rgba = has_rgb ? rgba_of(d.rgb, rgb_bits) : 0;
              r.attributes = pack_attributes(d.intensity, d.classification, d.return_number,
                                             d.number_of_returns);
              if (done + i == next_sample) {
                next_sample += sample_stride;
                samples[k].elevation.push_back(p.z);
                samples[k].intensity.push_back(double(d.intensity));
              }
            }
            done += n;
            if (options.report) options.report->done += n;
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
      if (options.report) options.report->done = seen;
      if (seen < info.point_count) spill();
    }
  }
  info.attributes.elevation_percentiles = percentile_range(std::move(elevation), {}, 0.02, 0.98);
  info.attributes.intensity_percentiles = percentile_range(std::move(intensity), {}, 0.02, 0.98);

  if (options.report) {
    options.report->done = 0;
    options.report->phase = 2;
  }
  // The cache, written under a temporary name: the points, the table, then the header.
  AtomicFile file(cache_path);
  const std::string name = cache_path.string();
  Fd out(::open(file.temp_path().c_str(), O_RDWR | O_CREAT | O_TRUNC | O_CLOEXEC, 0666));
  if (out.fd < 0) fail("{}: cannot write: {}", name, std::strerror(errno));
  PointletWriter writer(out.fd, name, info, origin, pool, stats);
  if (runs.files.empty()) {
    RunRecord* sorted = sort_run();
    RunRecord* other = other_of(sorted);
    // In whole pointlets, a sixteenth at a time when a reader follows the build: its progress
    // advances and a cancel is seen during the write (the cache is the same either way).
    const uint64_t k = info.pointlet_points;
    const uint64_t piece = options.report ? std::max<uint64_t>(k, run_size / 16 / k * k)
                                          : std::max<uint64_t>(run_size, 1);
    for (uint64_t at = 0; at < run_size; at += piece) {
      if (options.report && options.report->cancel)
        fail("{}: the cache build was cancelled", cache_path.string());
      const uint64_t n = std::min<uint64_t>(piece, run_size - at);
      writer.add(sorted + at, n, reinterpret_cast<PointletRecord*>(other));
      if (options.report) options.report->done += n;
    }
  } else {
    if (run_size > 0) spill();
    run_writes.wait();  // the runs are on disk before the merge reads them
    // The merge, in windows of key prefixes that hold at most a run's worth of points: each
    // window reads its part of every run (positional reads on every core), concatenated in run
    // order, and merges them (merge_window), ties in the runs' order, which is the input's.
    const uint32_t prefixes = prefix.count();
    std::vector<uint64_t> totals(prefixes, 0);
    for (const RunFile& r : runs.files)
      for (uint32_t b = 0; b < prefixes; ++b) totals[b] += r.starts[b + 1] - r.starts[b];
    Progress progress("writing pointlets", info.point_count);
    // A window is read into one buffer while the writer writes the last window's pointlets
    // from the other (PointletWriter: in the background); the merge then writes into that one,
    // once written.
    RunRecord* window = run_arena.runs();
    std::vector<uint64_t> punched(runs.files.size(), 0);  // blocks of each run freed so far
    // Frees the runs' blocks read whole; its destructor waits for the last (the runs' files
    // stay open until then: `runs` outlives it).
    ThreadPool puncher(1);
    for (const RunFile& r : runs.files) {
      stats.run_bytes += r.count * sizeof(RunRecord);
      for (const uint32_t b : r.block_bytes) stats.run_disk_bytes += b;
    }
    for (uint32_t b0 = 0; b0 < prefixes;) {
      uint32_t b1 = b0;
      uint64_t size = 0;
      while (b1 < prefixes && size + totals[b1] <= run_capacity) size += totals[b1++];
      if (b1 == b0) {
        // One prefix holds more than a run: merged by streaming its part of each run.
        writer.wait();
        merge_prefix(runs, b0, run_arena.runs(), run_capacity, scratch_arena.pointlets(), writer,
                     stats);
        window = run_arena.runs();  // the writer may be writing from the scratch buffer
        progress.advance(totals[b0]);
        if (options.report) options.report->done += totals[b0];
        if (options.report && options.report->cancel)
          fail("{}: the cache build was cancelled", cache_path.string());
        ++b0;
        continue;
      }
      if (size > 0) {
        struct Piece {
          const RunFile* run;
          uint64_t first, count, at;  // records of the run; index in the window
        };
        // A piece a block: each is read and decompressed on its own.
        std::vector<Piece> pieces;
        uint64_t at = 0;
        for (const RunFile& r : runs.files)
          for (uint64_t i = r.starts[b0]; i < r.starts[b1];) {
            const uint64_t n = std::min(kRunBlock - i % kRunBlock, r.starts[b1] - i);
            pieces.push_back({&r, i, n, at});
            at += n;
            i += n;
          }
        auto t = Clock::now();
        pool.parallel_for(pieces.size(), 1, [&](size_t begin, size_t end) {
          for (size_t i = begin; i < end; ++i)
            read_run_records(*pieces[i].run, pieces[i].first, pieces[i].count,
                             window + pieces[i].at);
        });
        // Blocks read whole are not read again: their disk space is freed, so that the runs
        // and the cache need not fit the disk together (1B points: 8.7 GB of runs, 20 GB of
        // cache). Where the file system cannot, the runs go when the build ends. On the
        // puncher's thread, off the merge's path: on ext4 a punch can wait for the dropped
        // pages' writeback (1B points on the H100 machine read their runs back in 13 s on its
        // disk, with no disk reads, against 3 s in /dev/shm: the likeliest cause).
        for (size_t i = 0; i < runs.files.size(); ++i) {
          const RunFile& r = runs.files[i];
          const uint64_t done =
              r.starts[b1] == r.count ? r.block_bytes.size() : r.starts[b1] / kRunBlock;
          if (done > punched[i])
            puncher.submit([fd = r.fd.fd, first = punched[i], done] {
              ::fallocate(fd, FALLOC_FL_PUNCH_HOLE | FALLOC_FL_KEEP_SIZE,
                          off_t(first * kRunBlockBytes), off_t((done - first) * kRunBlockBytes));
            });
          punched[i] = std::max(punched[i], done);
        }
        const double read_back = since(t);
        stats.merge_seconds += read_back;
        stats.run_read_seconds += read_back;
        writer.wait();  // the other buffer is where the window is merged to
        t = Clock::now();
        std::vector<WindowPart> parts;
        uint64_t part_at = 0;
        for (const RunFile& r : runs.files) {
          parts.push_back({r.starts.data(), part_at});
          part_at += r.starts[b1] - r.starts[b0];
        }
        RunRecord* sorted = other_of(window);
        merge_window(window, sorted, parts, totals, b0, b1, size, pool);
        stats.merge_seconds += since(t);
        writer.add(sorted, size, reinterpret_cast<PointletRecord*>(other_of(sorted)));
        window = sorted;  // encoded into the other: free for the next window
        progress.advance(size);
        if (options.report) options.report->done += size;
        if (options.report && options.report->cancel)
          fail("{}: the cache build was cancelled", cache_path.string());
      }
      b0 = b1;
    }
  }
  writer.flush();
  info.pointlet_count = writer.table.size();
  info.table_offset = info.points_offset + info.point_count * sizeof(PointletRecord);
  info.file_size = info.table_offset + info.pointlet_count * sizeof(PointletEntry);
  info.source_bounds = {};
  for (const PointletEntry& e : writer.table) {
    info.source_bounds.extend(glm::dvec3(e.min[0], e.min[1], e.min[2]));
    info.source_bounds.extend(glm::dvec3(e.max[0], e.max[1], e.max[2]));
  }
  const auto t = Clock::now();
  const uint64_t table_bytes = writer.table.size() * sizeof(PointletEntry);
  write_at(out.fd, writer.table.data(), table_bytes, info.table_offset, name);
  const std::vector<uint8_t> header =
      encode_header(info, crc32_of(writer.table.data(), table_bytes));
  write_at(out.fd, header.data(), header.size(), 0, name);
  if (::close(std::exchange(out.fd, -1)) != 0)
    fail("{}: cannot write: {} (disk full?)", name, std::strerror(errno));
  file.commit();
  stats.write_seconds += since(t);

  stats.points = info.point_count;
  stats.pointlets = info.pointlet_count;
  stats.pointlet_points = info.pointlet_points;
  stats.runs = std::max<uint64_t>(1, runs.files.size());
  stats.seconds = since(start);
  if (options.report) {
    options.report->done = info.point_count;
    options.report->phase = 3;
  }
  return stats;
}

double PointletBuildProgress::fraction() const {
  const uint32_t p = phase;
  if (p == 0) return 0;
  if (p >= 3) return 1;
  const double part = total > 0 ? std::min(1.0, double(done) / double(total)) : 0.0;
  return 0.5 * double(p - 1) + 0.5 * part;
}

// ---- reading --------------------------------------------------------------------------------
bool pointlet_cache_current(const std::vector<fs::path>& sources, const fs::path& cache_dir,
                            const PointletBuildOptions& options) {
  const fs::path path = pointlet_cache_path(sources, cache_dir, options);
  if (!fs::exists(path)) return false;
  try {
    return PointletCache::open(path).matches(sources, options);
  } catch (const Error&) {
    return false;  // open_pointlet_cache rebuilds it (and says why)
  }
}

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
  // Whole pages, within the file: a header naming many sources is longer.
  const uint32_t header_bytes = get<uint32_t>(h.data(), field::header_bytes);
  if (header_bytes < kPointletHeaderBytes || header_bytes % kPointletHeaderBytes != 0 ||
      header_bytes > kMaxHeaderBytes || header_bytes > storage_->size)
    fail("{}: header size {} (expected a multiple of {} within the file)", n, header_bytes,
         kPointletHeaderBytes);
  h.resize(header_bytes);
  storage_->read(n, 0, h.data(), h.size());
  const size_t header_crc = header_bytes - 4;
  PointletCacheInfo& i = info_;
  i.version = get<uint32_t>(h.data(), field::version);
  if (i.version != kPointletCacheVersion)
    fail("{}: pointlet cache version {}, this build reads version {}", n, i.version,
         kPointletCacheVersion);
  if (get<uint32_t>(h.data(), header_crc) != crc32_of(h.data(), header_crc))
    fail("{}: the header's checksum does not match (corrupt cache)", n);
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
  if (i.points_offset != header_bytes ||
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
    if (at + 26 > header_crc) fail("{}: the source list overruns the header", n);
    PointletSource src;
    src.size = get<uint64_t>(h.data(), at);
    src.mtime_ns = get<int64_t>(h.data(), at + 8);
    src.points = get<uint64_t>(h.data(), at + 16);
    const uint16_t len = get<uint16_t>(h.data(), at + 24);
    if (at + 26 + len > header_crc) fail("{}: the source list overruns the header", n);
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
