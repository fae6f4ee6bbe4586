#include "tiler_chunks.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <mutex>

#include "stipple/core/error.hpp"
#include "stipple/core/log.hpp"
#include "tiler_files.hpp"

namespace stipple::tiler::detail {

namespace {

// The count pyramid (level count_level at the bottom) cut top-down into the largest nodes of at
// most chunk_points points, and no coarser than the part level.
void cut_chunks(Build& b, const std::vector<uint32_t>& counts) {
  const int count_level = b.count_level;
  std::vector<std::vector<uint64_t>> pyramid(count_level + 1);
  pyramid[count_level].assign(counts.begin(), counts.end());
  for (int l = count_level - 1; l >= 0; --l) {
    const uint32_t n = 1u << l;
    pyramid[l].assign(size_t(n) * n * n, 0);
    const auto& fine = pyramid[l + 1];
    for (uint32_t z = 0; z < 2 * n; ++z)
      for (uint32_t y = 0; y < 2 * n; ++y)
        for (uint32_t x = 0; x < 2 * n; ++x)
          pyramid[l][((z / 2) * n + y / 2) * n + x / 2] +=
              fine[(size_t(z) * 2 * n + y) * 2 * n + x];
  }
  b.cell_chunk.assign(counts.size(), -1);
  std::vector<NodeKey> stack{NodeKey{}};
  while (!stack.empty()) {
    NodeKey k = stack.back();
    stack.pop_back();
    const uint32_t n = 1u << k.level;
    uint64_t c = pyramid[k.level][(size_t(k.z) * n + k.y) * n + k.x];
    if (c == 0) continue;
    if ((c > b.chunk_points || k.level < b.part_level) && k.level < count_level) {
      for (int i = 0; i < 8; ++i) stack.push_back(k.child(i));
      continue;
    }
    auto chunk = std::make_unique<Chunk>();
    chunk->key = k;
    chunk->file = b.tmp / ("chunk-" + k.name() + ".bin");
    // Mark the chunk's fine cells.
    const int shift = count_level - k.level;
    const uint32_t span = 1u << shift;
    for (uint32_t z = 0; z < span; ++z)
      for (uint32_t y = 0; y < span; ++y)
        for (uint32_t x = 0; x < span; ++x) {
          uint32_t cx = (k.x << shift) + x, cy = (k.y << shift) + y, cz = (k.z << shift) + z;
          b.cell_chunk[(cz << (2 * count_level)) | (cy << count_level) | cx] =
              int32_t(b.chunks.size());
        }
    b.chunks.push_back(std::move(chunk));
  }
}

// Out of core, chunks are kept in memory while their records fit half the budget (the counting
// pass told their sizes exactly); only the rest go to temporary files. Temporary files cost
// a kernel copy in and out, and beyond a few hundred MB of dirty pages the kernel throttles
// writers to the disk's speed.
void choose_resident_chunks(Build& b, const std::vector<uint32_t>& counts) {
  for (size_t cell = 0; cell < counts.size(); ++cell)
    if (b.cell_chunk[cell] >= 0) b.chunks[size_t(b.cell_chunk[cell])]->expected += counts[cell];
  const uint64_t budget = b.opt.max_memory / 2 / sizeof(TilePoint);
  uint64_t total = 0;
  for (auto& c : b.chunks) {
    if (total + c->expected > budget) continue;
    c->resident = true;
    c->offset = total;
    total += c->expected;
  }
  if (total) b.resident.reset(new TilePoint[total]);
  // The other chunks gather records in buffers of together a sixteenth of the budget, when
  // that makes buffers of at least 10 kB; smaller ones would save few writes.
  size_t spilled = 0;
  for (auto& c : b.chunks) spilled += !c->resident && c->expected > 0;
  if (spilled > 0) {
    const uint64_t per_chunk = b.opt.max_memory / 16 / sizeof(TilePoint) / spilled;
    b.chunk_buffer_points = per_chunk >= 256 ? size_t(std::min<uint64_t>(per_chunk, 65536)) : 0;
  }
  STIPPLE_INFO("tile: {} of {} points in chunks held in memory, the rest in temporary files", total,
               b.total_points);
}

}  // namespace

void plan_budget(Build& b, unsigned threads) {
  // Memory plan (bytes per point in flight): a read batch ~170 (PointBatch + local positions +
  // records + sorted copy); a point being indexed ~120 (twice its record + hash slots).
  const uint64_t budget = b.opt.max_memory;
  // Shares: 1/8 read batches, 1/4 indexing, the rest for the process itself, grids, allocator
  // slack and the upper levels.
  b.batch_points = std::clamp<uint64_t>(budget / 8 / ((threads + 2) * 170), 4096, 1 << 20);
  b.count_level = 7;
  while (b.count_level > 3 && (uint64_t(1) << (3 * b.count_level)) * 8 > budget / 8)
    --b.count_level;
  b.count_cells = double(1u << b.count_level);
  b.chunk_points = std::max<uint64_t>(budget / 4 / (threads * 120), 20000);
  // Staged records and resident chunks (2 x 40 bytes a point) within half the budget.
  b.in_memory = b.total_points * 2 * sizeof(TilePoint) <= budget / 2;
  if (b.in_memory) b.staged_mem.reset(new TilePoint[b.total_points]);
  if (b.part_level > b.count_level)
    fail(
        "--subset {}/{}: parts of level {} are finer than the count grid (level {}); use fewer "
        "parts or a larger --max-memory",
        b.opt.subset_index, b.opt.subset_count, b.part_level, b.count_level);
  STIPPLE_INFO(
      "tile: {} points from {} input(s), cube {:.1f} m, root spacing {:.3f} m, precision {:.4f} m, "
      "batches of {}, count grid {}^3, chunks of <= {} points, {} threads",
      b.total_points, b.inputs.size(), b.cube_size, b.root_spacing, b.content.precision,
      b.batch_points, 1 << b.count_level, b.chunk_points, threads);
}

size_t keep_in_part(const Build& b, TilePoint* recs, size_t n) {
  if (b.part_level == 0) return n;
  size_t kept = 0;
  for (size_t i = 0; i < n; ++i)
    if (cell_in_part(b, cell_of(b, recs[i]))) recs[kept++] = recs[i];
  return kept;
}

void plan_chunks(Build& b, std::vector<std::atomic<uint32_t>>& counts) {
  std::vector<uint32_t> plain(counts.size());
  for (size_t i = 0; i < counts.size(); ++i) plain[i] = counts[i].load();
  if (b.part_level > 0) {
    // From here on, the points are those of the part.
    b.total_points = 0;
    for (uint32_t c : plain) b.total_points += c;
    STIPPLE_INFO("tile: part {}/{} holds {} points", b.opt.subset_index, b.opt.subset_count,
                 b.total_points);
  }
  std::vector<std::atomic<uint32_t>>().swap(counts);
  cut_chunks(b, plain);
  if (!b.in_memory) choose_resident_chunks(b, plain);
}

void append_to_chunks(Build& b, const TilePoint* recs, size_t n) {
  thread_local std::vector<TilePoint> sorted;
  thread_local std::vector<int32_t> chunk_of;
  thread_local std::vector<uint32_t> offsets, fill;
  Profiler::Scope scope(&b.prof, Step::Distribute);
  chunk_of.resize(n);
  offsets.assign(b.chunks.size() + 1, 0);
  for (size_t i = 0; i < n; ++i) {
    chunk_of[i] = b.cell_chunk[cell_of(b, recs[i])];
    STIPPLE_ASSERT(chunk_of[i] >= 0, "a counted cell has no chunk");
    ++offsets[size_t(chunk_of[i]) + 1];
  }
  for (size_t c = 0; c < b.chunks.size(); ++c) offsets[c + 1] += offsets[c];
  fill.assign(offsets.begin(), offsets.end() - 1);
  sorted.resize(n);
  for (size_t i = 0; i < n; ++i) sorted[fill[size_t(chunk_of[i])]++] = recs[i];
  for (size_t c = 0; c < b.chunks.size(); ++c) {
    uint32_t s = offsets[c], e = offsets[c + 1];
    if (s == e) continue;
    Chunk& ch = *b.chunks[c];
    if (ch.resident) {
      // No lock: each writer reserves its own range of the chunk's counted place.
      const uint64_t at = ch.filled.fetch_add(e - s, std::memory_order_relaxed);
      if (at + (e - s) > ch.expected)
        fail("internal error: chunk {} receives more points than were counted", ch.key.name());
      std::memcpy(b.resident.get() + ch.offset + at, sorted.data() + s,
                  size_t(e - s) * sizeof(TilePoint));
      continue;
    }
    std::unique_lock lock(ch.mutex);
    if (b.chunk_buffer_points == 0) {
      Profiler::Scope write(&b.prof, Step::Write, size_t(e - s) * sizeof(TilePoint));
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
      if (run >= b.chunk_buffer_points) {
        lock.unlock();
        Profiler::Scope write(&b.prof, Step::Write, run * sizeof(TilePoint));
        append_file(ch.file, sorted.data() + s, run * sizeof(TilePoint));
        continue;
      }
      if (ch.pending.capacity() < b.chunk_buffer_points) ch.pending.reserve(b.chunk_buffer_points);
      if (ch.pending.size() + run > b.chunk_buffer_points) {
        full.reserve(b.chunk_buffer_points);
        full.swap(ch.pending);
      }
      ch.pending.insert(ch.pending.end(), sorted.begin() + s, sorted.begin() + e);
      lock.unlock();
      if (full.empty()) continue;
      Profiler::Scope write(&b.prof, Step::Write, full.size() * sizeof(TilePoint));
      append_file(ch.file, full.data(), full.size() * sizeof(TilePoint));
      full.clear();
    }
  }
}

void flush_chunk_buffers(Build& b) {
  b.pool->parallel_for(b.chunks.size(), 1, [&](size_t cb, size_t ce) {
    for (size_t c = cb; c < ce; ++c) {
      Chunk& ch = *b.chunks[c];
      if (ch.pending.empty()) continue;
      Profiler::Scope write(&b.prof, Step::Write, ch.pending.size() * sizeof(TilePoint));
      append_file(ch.file, ch.pending.data(), ch.pending.size() * sizeof(TilePoint));
      std::vector<TilePoint>().swap(ch.pending);
    }
  });
}

// In blocks read in parallel (pread).
void distribute(Build& b, const fs::path& staged, uint64_t count) {
  const FdCloser file{::open(staged.c_str(), O_RDONLY)};
  const int fd = file.fd;
  if (fd < 0) fail("{}: cannot open ({})", staged.string(), std::strerror(errno));
  const uint64_t block = b.batch_points;
  const size_t blocks = size_t((count + block - 1) / block);
  Progress progress("distributing", count);
  b.pool->parallel_for(blocks, 1, [&](size_t bb, size_t be) {
    thread_local std::vector<TilePoint> recs;
    for (size_t k = bb; k < be; ++k) {
      const uint64_t first = k * block;
      const size_t n = size_t(std::min<uint64_t>(block, count - first));
      recs.resize(n);
      char* dst = reinterpret_cast<char*>(recs.data());
      size_t want = n * sizeof(TilePoint);
      off_t at = off_t(first * sizeof(TilePoint));
      Profiler::Scope read(&b.prof, Step::ReadDecode, want);
      while (want > 0) {
        ssize_t r = ::pread(fd, dst, want, at);
        if (r <= 0) fail("{}: cannot read temporary points", staged.string());
        dst += r, want -= size_t(r), at += r;
      }
      append_to_chunks(b, recs.data(), n);
      std::lock_guard lock(b.progress_mutex);
      progress.advance(n);
    }
  });
  progress.finish();
}

// Chunk of every staged record, per-block histograms, then a parallel scatter straight into each
// chunk's exact-size range.
void distribute_in_memory(Build& b, uint64_t count) {
  const uint64_t block = b.batch_points;
  const size_t blocks = size_t((count + block - 1) / block), nc = b.chunks.size();
  const TilePoint* recs = b.staged_mem.get();
  Profiler::Scope scope(&b.prof, Step::Distribute);
  std::vector<uint32_t> chunk_of(count);
  std::vector<uint64_t> offsets(blocks * nc, 0);
  b.pool->parallel_for(blocks, 1, [&](size_t bb, size_t be) {
    for (size_t k = bb; k < be; ++k) {
      uint64_t* hist = &offsets[k * nc];
      const uint64_t end = std::min<uint64_t>(count, (k + 1) * block);
      for (uint64_t i = k * block; i < end; ++i) {
        int32_t c = b.cell_chunk[cell_of(b, recs[i])];
        STIPPLE_ASSERT(c >= 0, "a counted cell has no chunk");
        chunk_of[i] = uint32_t(c);
        ++hist[c];
      }
    }
  });
  uint64_t base = 0;
  for (size_t c = 0; c < nc; ++c) {
    Chunk& ch = *b.chunks[c];
    ch.offset = base;
    for (size_t k = 0; k < blocks; ++k) {
      uint64_t h = offsets[k * nc + c];
      offsets[k * nc + c] = base;
      base += h;
    }
    ch.count = base - ch.offset;
    ch.resident = true;
  }
  b.resident.reset(new TilePoint[count]);  // uninitialised: every slot is written below
  TilePoint* out = b.resident.get();
  b.pool->parallel_for(blocks, 1, [&](size_t bb, size_t be) {
    for (size_t k = bb; k < be; ++k) {
      uint64_t* fill = &offsets[k * nc];
      const uint64_t end = std::min<uint64_t>(count, (k + 1) * block);
      for (uint64_t i = k * block; i < end; ++i) out[fill[chunk_of[i]]++] = recs[i];
    }
  });
}

void check_distribution(Build& b) {
  uint64_t distributed = 0;
  for (auto& c : b.chunks) {
    if (!b.in_memory && c->resident) c->count = c->filled.load();
    distributed += c->count;
    if (!b.in_memory && c->resident && c->count != c->expected)
      fail("internal error: chunk {} holds {} points, {} were counted", c->key.name(), c->count,
           c->expected);
  }
  if (distributed != b.total_points)
    fail("the inputs hold {} points, not the {} their headers declare", distributed,
         b.total_points);
}

void split_oversized_chunks(Build& b) {
  for (size_t i = 0; i < b.chunks.size(); ++i) {
    Chunk& c = *b.chunks[i];
    if (c.count <= b.chunk_points * 3 / 2 || c.key.level >= b.max_level - 2) continue;
    if (c.resident) {
      write_file(c.file, b.resident.get() + c.offset, c.count * sizeof(TilePoint));
      c.resident = false;
    }
    std::vector<std::unique_ptr<Chunk>> kids(8);
    for (int k = 0; k < 8; ++k) {
      kids[k] = std::make_unique<Chunk>();
      kids[k]->key = c.key.child(k);
      kids[k]->file = b.tmp / ("chunk-" + kids[k]->key.name() + ".bin");
    }
    glm::dvec3 centre = node_min(b, c.key) + glm::dvec3(node_size(b, c.key.level + 1));
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
    b.chunks.erase(b.chunks.begin() + long(i));
    --i;
    for (auto& kid : kids)
      if (kid->count) b.chunks.push_back(std::move(kid));
  }
}

}  // namespace stipple::tiler::detail
