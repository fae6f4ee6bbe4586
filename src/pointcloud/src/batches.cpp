#include "stipple/pointcloud/batches.hpp"

#include <algorithm>
#include <array>
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

}  // namespace

uint32_t hilbert_from_morton(uint32_t morton30) {
  const HilbertTable& t = hilbert_table();
  uint32_t h = 0, state = 0;
  for (int shift = 27; shift >= 0; shift -= 3) {
    const uint32_t o = morton30 >> shift & 7;
    h = h << 3 | t.rank[state][o];
    state = t.next[state][o];
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

namespace {

// Below this many points one thread sorts and batches (tiles on streamer workers); above, the
// shared pool does (whole clouds, the first frame of `render` waits for them).
constexpr size_t kParallelBatching = size_t(1) << 21;

ThreadPool& batching_pool() {
  static ThreadPool pool;
  return pool;
}

// Cells of the curve are cubes: one scale for every axis of the bounding box.
double curve_scale(const Aabb& box) {
  const double extent = std::max({box.size().x, box.size().y, box.size().z, 1e-9});
  return double((1u << 21) - 1) / extent;
}

uint64_t curve_key(const glm::dvec3& p, const glm::dvec3& min, double scale, SpatialOrder order) {
  const glm::dvec3 c = (p - min) * scale;
  const uint32_t x = uint32_t(c.x), y = uint32_t(c.y), z = uint32_t(c.z);
  return order == SpatialOrder::Morton ? morton_key(x, y, z) : hilbert_key(x, y, z);
}

// Where batch_into writes: the batches and the per-point words, from the run's first index.
struct BatchTarget {
  uint64_t first_index;
  Batch* batches;
  uint32_t *coarse, *medium, *fine, *color;
};

// Batch c of the sorted run: its box over its points, then each point quantized in it.
void write_batch(std::span<const glm::dvec3> positions, std::span<const uint32_t> colors,
                 const std::vector<uint32_t>& perm, size_t c, uint32_t batch_points,
                 const BatchTarget& t) {
  const size_t b = c * batch_points, e = std::min(perm.size(), b + batch_points);
  Aabb box;
  for (size_t i = b; i < e; ++i) box.extend(positions[perm[i]]);
  Batch& batch = t.batches[c];
  batch.min = box.min;
  batch.size = box.size();
  batch.first = t.first_index + b;
  batch.count = uint32_t(e - b);
  for (size_t i = b; i < e; ++i) {
    const QuantizedPoint q = quantize(positions[perm[i]], batch.min, batch.size);
    t.coarse[i] = q.coarse;
    t.medium[i] = q.medium;
    t.fine[i] = q.fine;
    t.color[i] = colors[perm[i]];
  }
}

// The spatial sort of batch_into on every core, in the same total order (key, then index): the
// keys' top 12 bits split the points into 4096 key ranges (histograms and scatter per slice),
// each range is sorted on its own, and the batches are boxed and quantized in parallel.
size_t batch_into_parallel(std::span<const glm::dvec3> positions, std::span<const uint32_t> colors,
                           SpatialOrder order, uint32_t batch_points, uint64_t first_index,
                           Batch* batches, uint32_t* coarse, uint32_t* medium, uint32_t* fine,
                           uint32_t* color) {
  ThreadPool& pool = batching_pool();
  const size_t n = positions.size();
  const size_t slices = size_t(pool.size()) * 4;
  auto slice = [&](size_t s) { return std::pair{s * n / slices, (s + 1) * n / slices}; };
  std::vector<uint32_t> perm(n);
  if (order == SpatialOrder::None) {
    pool.parallel_for(n, 1 << 16, [&](size_t b, size_t e) {
      for (size_t i = b; i < e; ++i) perm[i] = uint32_t(i);
    });
  } else {
    std::vector<Aabb> boxes(slices);
    pool.parallel_for(slices, 1, [&](size_t sb, size_t se) {
      for (size_t s = sb; s < se; ++s) {
        auto [b, e] = slice(s);
        for (size_t i = b; i < e; ++i) boxes[s].extend(positions[i]);
      }
    });
    Aabb box;
    for (const auto& b : boxes) box.extend(b);
    const double scale = curve_scale(box);
    constexpr int kBucketBits = 12;
    constexpr size_t kBuckets = size_t(1) << kBucketBits;
    std::vector<uint64_t> keys(n);
    std::vector<uint32_t> histogram(slices * kBuckets, 0);
    pool.parallel_for(slices, 1, [&](size_t sb, size_t se) {
      for (size_t s = sb; s < se; ++s) {
        auto [b, e] = slice(s);
        uint32_t* h = &histogram[s * kBuckets];
        for (size_t i = b; i < e; ++i) {
          keys[i] = curve_key(positions[i], box.min, scale, order);
          ++h[keys[i] >> (63 - kBucketBits)];
        }
      }
    });
    // Bucket-major offsets: bucket k holds slice 0's points of k, then slice 1's, ...
    std::vector<uint64_t> start(slices * kBuckets);
    std::vector<uint64_t> bucket_start(kBuckets + 1, 0);
    uint64_t at = 0;
    for (size_t k = 0; k < kBuckets; ++k) {
      bucket_start[k] = at;
      for (size_t s = 0; s < slices; ++s) {
        start[s * kBuckets + k] = at;
        at += histogram[s * kBuckets + k];
      }
    }
    bucket_start[kBuckets] = at;
    std::vector<std::pair<uint64_t, uint32_t>> keyed(n);
    pool.parallel_for(slices, 1, [&](size_t sb, size_t se) {
      for (size_t s = sb; s < se; ++s) {
        auto [b, e] = slice(s);
        uint64_t* next = &start[s * kBuckets];
        for (size_t i = b; i < e; ++i)
          keyed[next[keys[i] >> (63 - kBucketBits)]++] = {keys[i], uint32_t(i)};
      }
    });
    pool.parallel_for(kBuckets, 16, [&](size_t kb, size_t ke) {
      for (size_t k = kb; k < ke; ++k) {
        std::sort(keyed.begin() + std::ptrdiff_t(bucket_start[k]),
                  keyed.begin() + std::ptrdiff_t(bucket_start[k + 1]));
        for (uint64_t i = bucket_start[k]; i < bucket_start[k + 1]; ++i) perm[i] = keyed[i].second;
      }
    });
  }
  const size_t count = (n + batch_points - 1) / batch_points;
  const BatchTarget target{first_index, batches, coarse, medium, fine, color};
  pool.parallel_for(count, 16, [&](size_t cb, size_t ce) {
    for (size_t c = cb; c < ce; ++c) write_batch(positions, colors, perm, c, batch_points, target);
  });
  return count;
}

// Sorts and batches one run of points, writing batches and per-point words at the given places.
// Returns the number of batches written (ceil(n / batch_points)).
size_t batch_into(std::span<const glm::dvec3> positions, std::span<const uint32_t> colors,
                  SpatialOrder order, uint32_t batch_points, uint64_t first_index, Batch* batches,
                  uint32_t* coarse, uint32_t* medium, uint32_t* fine, uint32_t* color) {
  const size_t n = positions.size();
  std::vector<uint32_t> perm(n);
  for (size_t i = 0; i < n; ++i) perm[i] = uint32_t(i);
  if (order != SpatialOrder::None && n > 1) {
    Aabb box;
    for (const auto& p : positions) box.extend(p);
    const double scale = curve_scale(box);
    std::vector<std::pair<uint64_t, uint32_t>> keyed(n);
    for (size_t i = 0; i < n; ++i)
      keyed[i] = {curve_key(positions[i], box.min, scale, order), uint32_t(i)};
    std::sort(keyed.begin(), keyed.end());
    for (size_t i = 0; i < n; ++i) perm[i] = keyed[i].second;
  }
  const size_t count = (n + batch_points - 1) / batch_points;
  const BatchTarget target{first_index, batches, coarse, medium, fine, color};
  for (size_t c = 0; c < count; ++c) write_batch(positions, colors, perm, c, batch_points, target);
  return count;
}

void finish_bounds(BatchedCloud& out) {
  out.world_bounds = Aabb{};
  for (const Batch& b : out.batches) {
    out.world_bounds.extend(b.min);
    out.world_bounds.extend(b.min + b.size);
  }
}

}  // namespace

void append_batches(BatchedCloud& out, std::span<const glm::dvec3> positions,
                    std::span<const uint32_t> colors, SpatialOrder order, uint32_t batch_points) {
  STIPPLE_ASSERT(positions.size() == colors.size(), "one colour per point");
  STIPPLE_ASSERT(batch_points > 0, "batches hold points");
  size_t base = out.color.size(), n = positions.size();
  size_t batch_base = out.batches.size();
  out.batches.resize(batch_base + (n + batch_points - 1) / batch_points);
  out.coarse.resize(base + n);
  out.medium.resize(base + n);
  out.fine.resize(base + n);
  out.color.resize(base + n);
  (n >= kParallelBatching ? batch_into_parallel : batch_into)(
      positions, colors, order, batch_points, base, out.batches.data() + batch_base,
      out.coarse.data() + base, out.medium.data() + base, out.fine.data() + base,
      out.color.data() + base);
  finish_bounds(out);
}

BatchedCloud build_batches(const PointCloud& cloud, SpatialOrder order, uint32_t batch_points,
                           const PointShading* shading) {
  // Gathered (and shaded) chunk by chunk on the batching pool for whole clouds.
  std::vector<size_t> first(cloud.chunks.size() + 1, 0);
  for (size_t c = 0; c < cloud.chunks.size(); ++c)
    first[c + 1] = first[c] + cloud.chunks[c].vertices.size();
  std::vector<glm::dvec3> positions(first.back());
  std::vector<uint32_t> colors(first.back());
  const ColorMode mode =
      shading ? resolve_color_mode(cloud.attributes, shading->mode) : ColorMode::Rgb;
  auto gather = [&](size_t cb, size_t ce) {
    for (size_t c = cb; c < ce; ++c) {
      const PointChunk& chunk = cloud.chunks[c];
      size_t i = first[c];
      for (const auto& v : chunk.vertices) {
        positions[i] = chunk.origin + glm::dvec3(v.x, v.y, v.z);
        colors[i++] =
            shading ? shade_point(*shading, mode, v, chunk.origin.y + double(v.y)) : v.rgba;
      }
    }
  };
  if (first.back() >= kParallelBatching)
    batching_pool().parallel_for(cloud.chunks.size(), 1, gather);
  else
    gather(0, cloud.chunks.size());
  BatchedCloud out;
  append_batches(out, positions, colors, order, batch_points);
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
  uint64_t batches_per_piece = piece / batch_points;
  BatchedCloud out;
  out.coarse.resize(n);
  out.medium.resize(n);
  out.fine.resize(n);
  out.color.resize(n);
  out.batches.resize((n + batch_points - 1) / batch_points);

  Progress bar(progress ? "generating" : "", progress ? n : 0);
  std::mutex bar_mutex;
  ThreadPool pool;
  pool.parallel_for(pieces, 1, [&](size_t begin, size_t end) {
    io::PointBatch generated;
    std::vector<glm::dvec3> positions;
    std::vector<uint32_t> colors;
    for (size_t p = begin; p < end; ++p) {
      uint64_t first = p * piece, count = std::min(piece, n - first);
      generated.clear();
      io::generate_scene(params, first, count, generated);
      positions.resize(count);
      colors.resize(count);
      for (size_t i = 0; i < count; ++i) {
        positions[i] = z_up_to_y_up(generated.positions[i]);
        auto c = generated.rgb[i];
        colors[i] = pack_rgba(uint8_t(c.r), uint8_t(c.g), uint8_t(c.b));
      }
      batch_into(positions, colors, order, batch_points, first,
                 out.batches.data() + p * batches_per_piece, out.coarse.data() + first,
                 out.medium.data() + first, out.fine.data() + first, out.color.data() + first);
      if (progress) {
        std::lock_guard lock(bar_mutex);
        bar.advance(count);
      }
    }
  });
  if (progress) bar.finish();
  finish_bounds(out);
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
