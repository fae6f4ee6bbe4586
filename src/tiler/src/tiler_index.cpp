#include "tiler_index.hpp"

#include <algorithm>
#include <array>
#include <mutex>
#include <span>
#include <vector>

#include "stipple/core/error.hpp"
#include "stipple/tiler/sampling.hpp"
#include "tiler_content.hpp"
#include "tiler_files.hpp"

namespace stipple::tiler::detail {

namespace {

// Works in place on its span: the points are partitioned into [child 0 .. child 7 | this node]
// and the children recurse on their sub-spans, so indexing allocates nothing per node.
void index_node(Build& b, const NodeKey& key, std::span<TilePoint> pts, bool chunk_root) {
  std::span<TilePoint> mine = pts;
  std::array<size_t, 9> starts{};
  if (pts.size() > b.opt.max_node_points && key.level < b.max_level) {
    thread_local std::vector<uint8_t> bucket;
    {
      Profiler::Scope sample(&b.prof, Step::Sample);
      grid_select(pts, node_min(b, key), spacing(b, key.level), b.opt.max_node_points, bucket);
    }
    Profiler::Scope index(&b.prof, Step::Index);
    const glm::dvec3 centre = node_min(b, key) + glm::dvec3(node_size(b, key.level + 1));
    const size_t n = pts.size();
    std::array<size_t, 9> sizes{};
    for (size_t i = 0; i < n; ++i) {
      const TilePoint& p = pts[i];
      uint8_t k =
          bucket[i]
              ? 8
              : uint8_t((p.x >= centre.x) | ((p.y >= centre.y) << 1) | ((p.z >= centre.z) << 2));
      bucket[i] = k;
      ++sizes[k];
    }
    // American flag sort: each point swapped straight into its bucket's region.
    std::array<size_t, 9> next{}, ends{};
    for (size_t k = 0, at = 0; k < 9; ++k) starts[k] = next[k] = at, at += sizes[k], ends[k] = at;
    for (size_t k = 0; k < 9; ++k) {
      while (next[k] < ends[k]) {
        const uint8_t c = bucket[next[k]];
        if (c == k) {
          ++next[k];
        } else {
          std::swap(pts[next[k]], pts[next[c]]);
          std::swap(bucket[next[k]], bucket[next[c]]);
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
    fs::path file = b.tmp / ("root-" + key.name() + ".bin");
    {
      Profiler::Scope write(&b.prof, Step::Write, mine.size() * sizeof(TilePoint));
      write_file(file, mine.data(), mine.size() * sizeof(TilePoint));
    }
    std::lock_guard lock(b.nodes_mutex);
    b.pending_roots[key] = file;
  } else {
    write_content(b, key, mine);
  }
  {
    std::lock_guard lock(b.progress_mutex);
    b.index_progress->advance(mine.size());
    b.indexed += mine.size();
    report(b, "indexing", b.indexed, b.total_points);
  }
  for (int i = 0; i < 8; ++i) {
    const size_t s = starts[i], e = i == 7 ? starts[8] : starts[i + 1];
    if (e > s) index_node(b, key.child(i), pts.subspan(s, e - s), false);
  }
}

void index_chunk(Build& b, size_t i) {
  Chunk& c = *b.chunks[i];
  thread_local std::vector<TilePoint> from_file;
  std::span<TilePoint> pts;
  if (c.resident) {
    pts = {b.resident.get() + c.offset, c.count};
  } else {
    Profiler::Scope read(&b.prof, Step::ReadDecode, c.count * sizeof(TilePoint));
    read_points(c.file, from_file);
    fs::remove(c.file);
    pts = from_file;
    if (pts.size() != c.count)
      fail("temporary chunk {} holds {} points, {} expected", c.key.name(), pts.size(), c.count);
  }
  index_node(b, c.key, pts, true);
}

}  // namespace

void index_chunks(Build& b) {
  // Biggest chunks first keeps the pool busy to the end.
  std::sort(b.chunks.begin(), b.chunks.end(), [](auto& x, auto& y) { return x->count > y->count; });
  b.index_progress = std::make_unique<Progress>("indexing", b.total_points);
  b.pool->parallel_for(b.chunks.size(), 1, [&](size_t cb, size_t ce) {
    for (size_t i = cb; i < ce; ++i) index_chunk(b, i);
  });
  b.resident.reset();
}

}  // namespace stipple::tiler::detail
