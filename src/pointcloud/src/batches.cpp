#include "stipple/pointcloud/batches.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <mutex>

#include "stipple/core/error.hpp"
#include "stipple/core/log.hpp"
#include "stipple/core/progress.hpp"
#include "stipple/core/thread_pool.hpp"
#include "stipple/io/point_batch.hpp"
#include "stipple/io/procedural.hpp"
#include "stipple/pointcloud/point_cloud.hpp"

namespace stipple::pc {

SpatialOrder parse_spatial_order(const std::string& name) {
  if (name == "none") return SpatialOrder::None;
  if (name == "morton") return SpatialOrder::Morton;
  if (name == "hilbert") return SpatialOrder::Hilbert;
  fail("unknown point order '{}' (none, morton, hilbert)", name);
}

namespace {
uint64_t spread3(uint32_t v) {
  // Spreads the low 21 bits so that bit i lands at bit 3i.
  uint64_t x = v & 0x1fffff;
  x = (x | x << 32) & 0x1f00000000ffffull;
  x = (x | x << 16) & 0x1f0000ff0000ffull;
  x = (x | x << 8) & 0x100f00f00f00f00full;
  x = (x | x << 4) & 0x10c30c30c30c30c3ull;
  x = (x | x << 2) & 0x1249249249249249ull;
  return x;
}
}  // namespace

uint64_t morton_key(uint32_t x, uint32_t y, uint32_t z) {
  return spread3(x) << 2 | spread3(y) << 1 | spread3(z);
}

uint64_t hilbert_key(uint32_t x, uint32_t y, uint32_t z) {
  // Skilling's transform (AIP Conf. Proc. 707, 2004): rotate/reflect the coordinates into the
  // "transposed" Hilbert index, whose interleaved bits are the key.
  constexpr int kBits = 21;
  uint32_t X[3] = {x & 0x1fffff, y & 0x1fffff, z & 0x1fffff};
  for (uint32_t q = 1u << (kBits - 1); q > 1; q >>= 1) {
    uint32_t p = q - 1;
    for (int i = 0; i < 3; ++i) {
      if (X[i] & q) {
        X[0] ^= p;  // invert the low bits of the first axis
      } else {
        uint32_t t = (X[0] ^ X[i]) & p;  // exchange the low bits of axis 0 and i
        X[0] ^= t;
        X[i] ^= t;
      }
    }
  }
  for (int i = 1; i < 3; ++i) X[i] ^= X[i - 1];  // Gray encode
  uint32_t t = 0;
  for (uint32_t q = 1u << (kBits - 1); q > 1; q >>= 1)
    if (X[2] & q) t ^= q - 1;
  for (uint32_t& v : X) v ^= t;
  return morton_key(X[0], X[1], X[2]);
}

namespace {

// The state table of the Hilbert curve that hilbert_key draws: per state, the rank of each of a
// cell's 8 children (by Morton octant, x the high bit) along the curve and the children's
// states. Derived once from hilbert_key itself (a cell's state is the order it visits its
// children in), so the two can never disagree.
struct HilbertTable {
  std::vector<std::array<uint8_t, 8>> rank, next;
};

const HilbertTable& hilbert_table() {
  static const HilbertTable table = [] {
    constexpr int kLevels = 10, kBits = 21;
    struct Cell {
      int level;
      uint32_t x, y, z;
    };
    auto child = [](const Cell& c, int o) {
      return Cell{c.level + 1, c.x << 1 | uint32_t(o >> 2 & 1), c.y << 1 | uint32_t(o >> 1 & 1),
                  c.z << 1 | uint32_t(o & 1)};
    };
    // The order in which a cell's children are visited: their keys at a representative point.
    auto ranks = [&](const Cell& c) {
      std::array<std::pair<uint64_t, int>, 8> keys;
      for (int o = 0; o < 8; ++o) {
        Cell k = child(c, o);
        const int shift = kBits - k.level;
        keys[o] = {hilbert_key(k.x << shift, k.y << shift, k.z << shift), o};
      }
      std::sort(keys.begin(), keys.end());
      std::array<uint8_t, 8> r{};
      for (int i = 0; i < 8; ++i) r[keys[i].second] = uint8_t(i);
      return r;
    };
    HilbertTable t;
    std::vector<Cell> representative;
    auto state_of = [&](const Cell& c) {
      auto r = ranks(c);
      for (size_t s = 0; s < t.rank.size(); ++s)
        if (t.rank[s] == r) return uint8_t(s);
      t.rank.push_back(r);
      t.next.push_back({});
      representative.push_back(c);
      return uint8_t(t.rank.size() - 1);
    };
    state_of(Cell{0, 0, 0, 0});
    for (size_t s = 0; s < t.rank.size(); ++s) {
      const Cell c = representative[s];
      if (c.level + 1 >= kLevels)
        fail("hilbert_table: the states did not close by level {}", kLevels);
      for (int o = 0; o < 8; ++o) t.next[s][o] = state_of(child(c, o));
    }
    return t;
  }();
  return table;
}

// Two levels a step, from hilbert_table: per state and pair of octants (six Morton bits), the
// two ranks (six Hilbert bits) and the state after them, in one word (rank | state << 6). Half
// the steps of the dependent chain, one load each: the cache build computes a key per point.
// (States are 8-bit, so a word holds both.)
const std::vector<std::array<uint16_t, 64>>& hilbert_pair_table() {
  static const std::vector<std::array<uint16_t, 64>> table = [] {
    const HilbertTable& t = hilbert_table();
    std::vector<std::array<uint16_t, 64>> pairs(t.rank.size());
    for (size_t s = 0; s < t.rank.size(); ++s)
      for (uint32_t o = 0; o < 64; ++o) {
        const uint32_t high = o >> 3, low = o & 7, middle = t.next[s][high];
        const uint32_t rank = uint32_t(t.rank[s][high]) << 3 | t.rank[middle][low];
        pairs[s][o] = uint16_t(rank | uint32_t(t.next[middle][low]) << 6);
      }
    return pairs;
  }();
  return table;
}

}  // namespace

uint32_t hilbert_from_morton(uint32_t morton30) {
  const std::array<uint16_t, 64>* rows = hilbert_pair_table().data();
  uint32_t h = 0, state = 0;
  for (int shift = 24; shift >= 0; shift -= 6) {
    const uint32_t step = rows[state][morton30 >> shift & 63];
    h = h << 6 | (step & 63);
    state = step >> 6;
  }
  return h;
}

QuantizedPoint quantize(const glm::dvec3& p, const glm::dvec3& min, const glm::dvec3& size) {
  constexpr double kScale = double(1u << 30);
  uint32_t q[3];
  for (int a = 0; a < 3; ++a) {
    double t = size[a] > 0 ? (p[a] - min[a]) / size[a] : 0.0;
    q[a] = uint32_t(std::clamp(std::floor(t * kScale), 0.0, kScale - 1));
  }
  auto part = [&](int shift) {
    return (q[0] >> shift & 1023u) | (q[1] >> shift & 1023u) << 10 | (q[2] >> shift & 1023u) << 20;
  };
  return {part(20), part(10), part(0)};
}

glm::dvec3 dequantize(const QuantizedPoint& q, int bits, const glm::dvec3& min,
                      const glm::dvec3& size) {
  glm::dvec3 p;
  for (int a = 0; a < 3; ++a) {
    int s = 10 * a;
    double v = double(q.coarse >> s & 1023u) * 0x1p-10;
    if (bits >= 20) v += double(q.medium >> s & 1023u) * 0x1p-20;
    if (bits >= 30) v += double(q.fine >> s & 1023u) * 0x1p-30;
    v += bits >= 30 ? 0x1p-31 : bits >= 20 ? 0x1p-21 : 0x1p-11;  // cell centre
    p[a] = min[a] + v * size[a];
  }
  return p;
}

ThreadPool& batching_pool() {
  static ThreadPool pool;
  return pool;
}

uint32_t curve_key30(const glm::dvec3& p, const glm::dvec3& min, double extent,
                     SpatialOrder order) {
  const double scale = 1024.0 / std::max(extent, 1e-9);
  auto cell = [&](int a) {
    const double t = (p[a] - min[a]) * scale;
    return t <= 0.0 ? 0u : t >= 1023.0 ? 1023u : uint32_t(t);
  };
  const uint32_t morton = uint32_t(morton_key(cell(0), cell(1), cell(2)));
  return order == SpatialOrder::Hilbert ? hilbert_from_morton(morton) : morton;
}

namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

// Below this many points one thread sorts and batches; above, the shared pool does (whole
// clouds: the first frame of `render` waits for them).
constexpr size_t kParallelBatching = size_t(1) << 20;

// Runs fn(slice, begin, end) over `slices` equal parts of [0, n): on the pool, or inline.
template <typename Fn>
void for_slices(ThreadPool* pool, size_t n, size_t slices, Fn&& fn) {
  auto bounds = [&](size_t s) { return std::pair{s * n / slices, (s + 1) * n / slices}; };
  if (!pool || slices == 1) {
    for (size_t s = 0; s < slices; ++s) {
      auto [b, e] = bounds(s);
      fn(s, b, e);
    }
    return;
  }
  pool->parallel_for(slices, 1, [&](size_t sb, size_t se) {
    for (size_t s = sb; s < se; ++s) {
      auto [b, e] = bounds(s);
      fn(s, b, e);
    }
  });
}

// Points given as flat arrays.
struct FlatPoints {
  std::span<const glm::dvec3> positions;
  std::span<const uint32_t> colors, attributes;
  size_t size() const { return positions.size(); }
  glm::dvec3 position(size_t i) const { return positions[i]; }
  void point(size_t i, glm::dvec3& p, uint32_t& rgba, uint32_t& attr) const {
    p = positions[i];
    rgba = colors[i];
    attr = attributes.empty() ? kDefaultAttributes : attributes[i];
  }
  static constexpr uint32_t kDefaultAttributes = 1u << 16 | 1u << 24 | 1u << 28;
};

// Points given as chunks: point i is found through a table of which chunk holds the first index
// of each block of 2^16 indices, then a short walk (chunks are mostly far larger than a block).
struct ChunkPoints {
  std::span<const PointChunk> chunks;
  std::vector<uint64_t> first;     // per chunk, and the total at the end
  std::vector<uint32_t> at_block;  // chunk holding index block << kBlockBits
  static constexpr int kBlockBits = 16;

  explicit ChunkPoints(std::span<const PointChunk> c) : chunks(c), first(c.size() + 1, 0) {
    for (size_t k = 0; k < c.size(); ++k) first[k + 1] = first[k] + c[k].vertices.size();
    at_block.resize((first.back() >> kBlockBits) + 1);
    size_t k = 0;
    for (size_t b = 0; b < at_block.size(); ++b) {
      while (k + 1 < c.size() && first[k + 1] <= (uint64_t(b) << kBlockBits)) ++k;
      at_block[b] = uint32_t(k);
    }
  }
  size_t size() const { return first.back(); }
  const PointChunk::Vertex& vertex(size_t i, const PointChunk*& chunk) const {
    size_t k = at_block[i >> kBlockBits];
    while (first[k + 1] <= i) ++k;
    chunk = &chunks[k];
    return chunks[k].vertices[i - first[k]];
  }
  glm::dvec3 position(size_t i) const {
    const PointChunk* c;
    const auto& v = vertex(i, c);
    return c->origin + glm::dvec3(v.x, v.y, v.z);
  }
  void point(size_t i, glm::dvec3& p, uint32_t& rgba, uint32_t& attr) const {
    const PointChunk* c;
    const auto& v = vertex(i, c);
    p = c->origin + glm::dvec3(v.x, v.y, v.z);
    rgba = v.rgba;
    attr = v.attributes;
  }
  // Walks [b, e) in order without the lookup per point.
  template <typename Fn>
  void each(size_t b, size_t e, Fn&& fn) const {
    if (b >= e) return;
    size_t k = at_block[b >> kBlockBits];
    while (first[k + 1] <= b) ++k;
    for (size_t i = b; i < e;) {
      while (first[k + 1] <= i) ++k;
      const PointChunk& c = chunks[k];
      const size_t stop = std::min<size_t>(e, first[k + 1]);
      for (; i < stop; ++i) fn(i, c.origin, c.vertices[i - first[k]]);
    }
  }
};

template <typename Points, typename Fn>
void each_position(const Points& pts, size_t b, size_t e, Fn&& fn) {
  if constexpr (std::is_same_v<Points, ChunkPoints>) {
    pts.each(b, e, [&](size_t i, const glm::dvec3& origin, const PointChunk::Vertex& v) {
      fn(i, origin + glm::dvec3(v.x, v.y, v.z));
    });
  } else {
    for (size_t i = b; i < e; ++i) fn(i, pts.position(i));
  }
}

double cube_extent(const Aabb& box) {
  return std::max({box.size().x, box.size().y, box.size().z, 1e-9});
}

// Stable LSD radix sort of packed entries (key << 32 | index) by their 30-bit keys: three
// passes of 10 bits, each a histogram per slice then a scatter per slice. Entries come in
// index order, so the result is in (key, index) order. `tmp` is scratch of the same size.
void radix_sort30(ThreadPool* pool, std::span<uint64_t> entries, std::span<uint64_t> tmp,
                  size_t slices) {
  constexpr int kDigitBits = 10;
  constexpr size_t kBuckets = size_t(1) << kDigitBits;
  const size_t n = entries.size();
  std::vector<uint64_t> offsets(slices * kBuckets);
  std::span<uint64_t> src = entries, dst = tmp;
  for (int pass = 0; pass < 3; ++pass) {
    const int shift = 32 + pass * kDigitBits;
    for_slices(pool, n, slices, [&](size_t s, size_t b, size_t e) {
      uint64_t* h = &offsets[s * kBuckets];
      std::fill(h, h + kBuckets, 0);
      for (size_t i = b; i < e; ++i) ++h[src[i] >> shift & (kBuckets - 1)];
    });
    uint64_t at = 0;
    for (size_t k = 0; k < kBuckets; ++k)
      for (size_t s = 0; s < slices; ++s) {
        const uint64_t c = offsets[s * kBuckets + k];
        offsets[s * kBuckets + k] = at;
        at += c;
      }
    for_slices(pool, n, slices, [&](size_t s, size_t b, size_t e) {
      uint64_t* next = &offsets[s * kBuckets];
      for (size_t i = b; i < e; ++i) dst[next[src[i] >> shift & (kBuckets - 1)]++] = src[i];
    });
    std::swap(src, dst);
  }
  // Three passes end in `tmp`.
  if (src.data() != entries.data()) std::copy(src.begin(), src.end(), entries.begin());
}

// The sorted order of `pts` as packed entries (key << 32 | index).
template <typename Points>
UninitVector<uint64_t> curve_order(const Points& pts, SpatialOrder order, uint32_t batch_points,
                                   ThreadPool* pool, BatchBuildStats& stats) {
  const size_t n = pts.size();
  const size_t slices = pool ? size_t(pool->size()) * 4 : 1;
  UninitVector<uint64_t> entries(n);
  if (order == SpatialOrder::None) {
    for_slices(pool, n, slices, [&](size_t, size_t b, size_t e) {
      for (size_t i = b; i < e; ++i) entries[i] = i;
    });
    return entries;
  }
  auto t = Clock::now();
  std::vector<Aabb> boxes(slices);
  for_slices(pool, n, slices, [&](size_t s, size_t b, size_t e) {
    Aabb box;
    each_position(pts, b, e, [&](size_t, const glm::dvec3& p) { box.extend(p); });
    boxes[s] = box;
  });
  Aabb box;
  for (const Aabb& b : boxes) box.extend(b);
  stats.bounds_s += seconds_since(t);
  t = Clock::now();
  const double extent = cube_extent(box);
  for_slices(pool, n, slices, [&](size_t, size_t b, size_t e) {
    each_position(pts, b, e, [&](size_t i, const glm::dvec3& p) {
      entries[i] = uint64_t(curve_key30(p, box.min, extent, order)) << 32 | i;
    });
  });
  stats.keys_s += seconds_since(t);
  t = Clock::now();
  {
    UninitVector<uint64_t> tmp(n);
    radix_sort30(pool, entries, tmp, slices);
  }
  stats.sort_s += seconds_since(t);

  // Cells holding more than a batch: their points ordered again by keys in the cell's own box,
  // down to cells that hold at most a batch or whose points all coincide.
  t = Clock::now();
  struct Run {
    size_t b, e;
    int depth;
  };
  // Runs of one key longer than a batch that start in [b, e) (and end by `limit`).
  auto over_full = [&](size_t b, size_t e, size_t limit, int depth, std::vector<Run>& out) {
    size_t i = b;
    while (i > 0 && i < e && (entries[i] >> 32) == (entries[i - 1] >> 32)) ++i;
    while (i < e) {
      size_t j = i + 1;
      while (j < limit && (entries[j] >> 32) == (entries[i] >> 32)) ++j;
      if (j - i > batch_points) out.push_back({i, j, depth});
      i = j;
    }
  };
  std::vector<Run> runs;
  std::mutex runs_mutex;
  for_slices(pool, n, slices, [&](size_t, size_t b, size_t e) {
    std::vector<Run> found;
    over_full(b, e, n, 0, found);
    std::lock_guard lock(runs_mutex);
    runs.insert(runs.end(), found.begin(), found.end());
  });
  while (!runs.empty()) {
    stats.refined_cells += runs.size();
    std::vector<Run> next;
    auto refine = [&](size_t rb, size_t re) {
      std::vector<uint64_t> tmp;
      std::vector<Run> found;
      for (size_t r = rb; r < re; ++r) {
        const Run run = runs[r];
        Aabb cell;
        for (size_t i = run.b; i < run.e; ++i) cell.extend(pts.position(entries[i] & 0xffffffffu));
        const double ext = std::max({cell.size().x, cell.size().y, cell.size().z});
        if (!(ext > 0.0) || run.depth >= 6) continue;  // coincident points: any order
        for (size_t i = run.b; i < run.e; ++i) {
          const uint64_t index = entries[i] & 0xffffffffu;
          entries[i] =
              uint64_t(curve_key30(pts.position(index), cell.min, ext, order)) << 32 | index;
        }
        std::span<uint64_t> part(entries.data() + run.b, run.e - run.b);
        // The run is in index order (stable sorts from index order), as radix_sort30 needs.
        tmp.resize(part.size());
        radix_sort30(nullptr, part, tmp, 1);
        over_full(run.b, run.e, run.e, run.depth + 1, found);
      }
      std::lock_guard lock(runs_mutex);
      next.insert(next.end(), found.begin(), found.end());
    };
    if (pool && runs.size() > 1)
      pool->parallel_for(runs.size(), 1, refine);
    else
      refine(0, runs.size());
    std::sort(next.begin(), next.end(), [](const Run& a, const Run& b) { return a.b < b.b; });
    runs = std::move(next);
  }
  stats.refine_s += seconds_since(t);
  return entries;
}

// Sorts and batches `pts`, appending to `out`.
template <typename Points>
void batch_points_into(BatchedCloud& out, const Points& pts, const BatchingOptions& options) {
  STIPPLE_ASSERT(options.batch_points > 0, "batches hold points");
  const size_t n = pts.size();
  if (n >= (uint64_t(1) << 32)) fail("batching indexes points with 32 bits: {} points", n);
  BatchBuildStats local;
  BatchBuildStats& stats = options.stats ? *options.stats : local;
  ThreadPool* pool = options.parallel && n >= kParallelBatching ? &batching_pool() : nullptr;
  const UninitVector<uint64_t> order =
      curve_order(pts, options.order, options.batch_points, pool, stats);

  auto t = Clock::now();
  const uint32_t bp = options.batch_points;
  const size_t base = out.color.size(), batch_base = out.batches.size();
  const size_t count = (n + bp - 1) / bp;
  out.batches.resize(batch_base + count);
  for (PointWords* w : {&out.coarse, &out.medium, &out.fine, &out.color, &out.attributes})
    w->resize(base + n);
  auto write = [&](size_t cb, size_t ce) {
    std::vector<glm::dvec3> positions(bp);
    for (size_t c = cb; c < ce; ++c) {
      const size_t b = c * bp, e = std::min(n, b + bp);
      Aabb box;
      for (size_t i = b; i < e; ++i) {
        const size_t index = order[i] & 0xffffffffu;
        pts.point(index, positions[i - b], out.color[base + i], out.attributes[base + i]);
        box.extend(positions[i - b]);
      }
      Batch& batch = out.batches[batch_base + c];
      batch.min = box.min;
      batch.size = box.size();
      batch.first = base + b;
      batch.count = uint32_t(e - b);
      for (size_t i = b; i < e; ++i) {
        const QuantizedPoint q = quantize(positions[i - b], batch.min, batch.size);
        const bool translucent = options.mark_translucent && (out.color[base + i] >> 24) < 255;
        out.coarse[base + i] = q.coarse | (translucent ? kTranslucentBit : 0u);
        out.medium[base + i] = q.medium;
        out.fine[base + i] = q.fine;
      }
    }
  };
  if (pool)
    pool->parallel_for(count, 4, write);
  else
    write(0, count);
  stats.write_s += seconds_since(t);
  out.world_bounds = Aabb{};
  for (const Batch& b : out.batches) {
    out.world_bounds.extend(b.min);
    out.world_bounds.extend(b.min + b.size);
  }
}

}  // namespace

void append_batches(BatchedCloud& out, std::span<const glm::dvec3> positions,
                    std::span<const uint32_t> colors, std::span<const uint32_t> attributes,
                    const BatchingOptions& options) {
  STIPPLE_ASSERT(positions.size() == colors.size(), "one colour per point");
  STIPPLE_ASSERT(attributes.empty() || attributes.size() == positions.size(),
                 "one attribute word per point");
  batch_points_into(out, FlatPoints{positions, colors, attributes}, options);
}

void append_batches(BatchedCloud& out, std::span<const glm::dvec3> positions,
                    std::span<const uint32_t> colors, SpatialOrder order, uint32_t batch_points,
                    std::span<const uint32_t> attributes) {
  BatchingOptions options;
  options.order = order;
  options.batch_points = batch_points;
  append_batches(out, positions, colors, attributes, options);
}

void append_chunk_batches(BatchedCloud& out, std::span<const PointChunk> chunks,
                          const BatchingOptions& options) {
  batch_points_into(out, ChunkPoints(chunks), options);
}

BatchedCloud build_batches(const PointCloud& cloud, const BatchingOptions& options) {
  BatchedCloud out;
  BatchingOptions o = options;
  o.mark_translucent = o.mark_translucent || cloud.attributes.has_translucent;
  append_chunk_batches(out, cloud.chunks, o);
  return out;
}

BatchedCloud generate_batched_scene(const io::SceneParams& params, SpatialOrder order,
                                    uint32_t batch_points, bool progress) {
  // The scene is scanned line by line, so a run of consecutive indices is a strip across it;
  // runs of ~128 sqrt(N) points make strips about as tall as a batch is wide.
  uint64_t n = params.point_count;
  uint64_t piece =
      std::clamp<uint64_t>(uint64_t(128.0 * std::sqrt(double(n))) / batch_points * batch_points,
                           uint64_t(batch_points) * 64, uint64_t(batch_points) * 800);
  uint64_t pieces = (n + piece - 1) / piece;
  BatchedCloud out;
  for (PointWords* w : {&out.coarse, &out.medium, &out.fine, &out.color, &out.attributes})
    w->resize(n);
  out.batches.resize((n + batch_points - 1) / batch_points);

  Progress bar(progress ? "generating" : "", progress ? n : 0);
  std::mutex bar_mutex;
  ThreadPool pool;
  pool.parallel_for(pieces, 1, [&](size_t begin, size_t end) {
    io::PointBatch generated;
    std::vector<glm::dvec3> positions;
    std::vector<uint32_t> colors, attributes;
    BatchingOptions options;
    options.order = order;
    options.batch_points = batch_points;
    options.parallel = false;
    for (size_t p = begin; p < end; ++p) {
      uint64_t first = p * piece, count = std::min(piece, n - first);
      generated.clear();
      io::generate_scene(params, first, count, generated);
      positions.resize(count);
      colors.resize(count);
      attributes.resize(count);
      for (size_t i = 0; i < count; ++i) {
        positions[i] = z_up_to_y_up(generated.positions[i]);
        colors[i] = batch_rgba(generated, i, 8);
        attributes[i] = batch_attributes(generated, i);
      }
      // Batched on its own, then moved into place (pieces hold whole batches).
      BatchedCloud part;
      append_batches(part, positions, colors, attributes, options);
      std::copy(part.batches.begin(), part.batches.end(),
                out.batches.begin() + std::ptrdiff_t(first / batch_points));
      for (size_t b = 0; b < part.batches.size(); ++b)
        out.batches[first / batch_points + b].first += first;
      auto place = [&](const PointWords& from, PointWords& to) {
        std::copy(from.begin(), from.end(), to.begin() + std::ptrdiff_t(first));
      };
      place(part.coarse, out.coarse);
      place(part.medium, out.medium);
      place(part.fine, out.fine);
      place(part.color, out.color);
      place(part.attributes, out.attributes);
      if (progress) {
        std::lock_guard lock(bar_mutex);
        bar.advance(count);
      }
    }
  });
  if (progress) bar.finish();
  out.world_bounds = Aabb{};
  for (const Batch& b : out.batches) {
    out.world_bounds.extend(b.min);
    out.world_bounds.extend(b.min + b.size);
  }
  return out;
}

// ---- culling ---------------------------------------------------------------------------------

int precision_bits(float size_px) {
  // Half the quantization grid in pixels (seed 001, section 3.3): no new holes from rounding.
  return size_px < 500.0f ? 10 : size_px < 500'000.0f ? 20 : 30;
}

BatchVisibility classify_batch(const glm::mat4& view_proj, const glm::vec3& offset,
                               const glm::vec3& size, const CullSettings& settings) {
  BatchVisibility v;
  bool out[5] = {true, true, true, true, true};  // left, right, bottom, top, near
  bool behind = false;
  glm::vec2 lo(std::numeric_limits<float>::infinity()), hi(-std::numeric_limits<float>::infinity());
  for (int i = 0; i < 8; ++i) {
    glm::vec3 corner =
        offset + size * glm::vec3(float(i & 1), float(i >> 1 & 1), float(i >> 2 & 1));
    glm::vec4 c = view_proj * glm::vec4(corner, 1.0f);
    out[0] = out[0] && c.x < -c.w;
    out[1] = out[1] && c.x > c.w;
    out[2] = out[2] && c.y < -c.w;
    out[3] = out[3] && c.y > c.w;
    out[4] = out[4] && c.z > c.w;  // reverse Z: nearer than the near plane
    if (c.z > c.w || c.w <= 0.0f) {
      behind = true;
    } else {
      glm::vec2 s(c.x / c.w * 0.5f + 0.5f, 0.5f - c.y / c.w * 0.5f);
      s *= glm::vec2(float(settings.width), float(settings.height));
      lo = glm::min(lo, s);
      hi = glm::max(hi, s);
    }
  }
  if (out[0] || out[1] || out[2] || out[3] || out[4]) return v;
  v.size_px = behind ? std::numeric_limits<float>::infinity() : std::max(hi.x - lo.x, hi.y - lo.y);
  if (v.size_px < settings.min_batch_px) {
    v.lod_skip = true;
    return v;
  }
  v.visible = true;
  v.bits = settings.force_bits ? settings.force_bits : precision_bits(v.size_px);
  return v;
}

glm::mat4 raster_view_proj(const Camera& camera, uint32_t width, uint32_t height) {
  return glm::mat4(camera.projection(double(width) / height) * camera.view_rotation());
}

RasterCounters reference_counters(const std::vector<Batch>& batches, const Camera& camera,
                                  const CullSettings& settings) {
  RasterCounters c;
  glm::mat4 vp = raster_view_proj(camera, settings.width, settings.height);
  for (const Batch& b : batches) {
    ++c.batches_processed;
    BatchVisibility v =
        classify_batch(vp, glm::vec3(b.min - camera.position), glm::vec3(b.size), settings);
    if (v.lod_skip) ++c.batches_lod_skipped;
    if (!v.visible) {
      if (!v.lod_skip) ++c.batches_culled;
      continue;
    }
    ++c.batches_rendered;
    c.points_rendered += b.count;
    int k = v.bits / 10 - 1;
    ++c.batches_by_bits[k];
    c.points_by_bits[k] += b.count;
  }
  return c;
}

}  // namespace stipple::pc
