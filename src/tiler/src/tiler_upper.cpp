#include "tiler_upper.hpp"

#include <algorithm>
#include <condition_variable>
#include <map>
#include <mutex>
#include <utility>
#include <vector>

#include "stipple/core/error.hpp"
#include "stipple/tiler/sampling.hpp"
#include "tiler_content.hpp"
#include "tiler_files.hpp"

namespace stipple::tiler::detail {

void build_upper_levels(Build& b) {
  const TileOptions& opt = b.opt;
  // The nodes above the chunk roots, down to the part level: every root deeper than that is
  // merged into its parent, and so is every parent made. Kids in key order, as ever.
  std::map<NodeKey, fs::path> file;  // of every root and every parent to make
  std::map<NodeKey, std::vector<NodeKey>> kids_of;
  for (auto& [k, f] : b.pending_roots) file[k] = f;
  for (auto& [k, f] : b.pending_roots) {
    for (NodeKey n = k; n.level > b.part_level; n = n.parent()) {
      const NodeKey p = n.parent();
      const bool made_before = kids_of.count(p) > 0;
      kids_of[p].push_back(n);
      if (made_before) break;  // its ancestors are listed already
      if (file.count(p)) fail("internal error: chunk root {} lies above another", p.name());
      file[p] = b.tmp / ("root-" + p.name() + ".bin");
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
    const uint64_t quarter = opt.max_memory / 4;
    auto bytes_for = [&](const NodeKey& parent) {
      uint64_t bytes = opt.max_node_points * sizeof(TilePoint);
      for (const NodeKey& k : kids_of.at(parent)) {
        std::error_code ec;
        const uint64_t size = fs::file_size(file.at(k), ec);
        bytes += ec ? opt.max_node_points * sizeof(TilePoint) : size;
      }
      return 2 * bytes;
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
        Profiler::Scope read(&b.prof, Step::ReadDecode);
        std::vector<TilePoint> p = read_points(file.at(k));
        read.add_bytes(p.size() * sizeof(TilePoint));
        all.insert(all.end(), p.begin(), p.end());
        ends.push_back(all.size());
      }
      std::vector<uint8_t> selected;
      {
        Profiler::Scope sample(&b.prof, Step::Sample);
        grid_select(all, node_min(b, parent), spacing(b, parent.level), opt.max_node_points,
                    selected);
      }
      std::vector<TilePoint> up;
      size_t at = 0;
      for (size_t c = 0; c < kids.size(); ++c) {
        std::vector<TilePoint> stay;
        for (; at < ends[c]; ++at) (selected[at] ? up : stay).push_back(all[at]);
        write_content(b, kids[c], stay);
        fs::remove(file.at(kids[c]));
      }
      Profiler::Scope write(&b.prof, Step::Write, up.size() * sizeof(TilePoint));
      write_file(file.at(parent), up.data(), up.size() * sizeof(TilePoint));
    };
    uint64_t reserved = 0;
    size_t running = 0;
    // A budget that fits one parent of full kids at most runs them here, one at a time.
    const uint64_t full = 9 * opt.max_node_points * sizeof(TilePoint) * 2;
    const size_t lanes =
        quarter / full <= 1 ? 1 : std::clamp<size_t>(b.pool->size(), 1, kids_of.size());
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
        if (parent.level > b.part_level && --waiting.at(parent.parent()) == 0)
          ready.emplace_back(parent.parent(), bytes_for(parent.parent()));
        wake.notify_all();
      }
    };
    // One lane runs here: the memory freed by this thread is what it reuses (a worker's malloc
    // arena would keep its own, and a tight budget counts both).
    if (lanes == 1)
      lane(0, 1);
    else
      b.pool->parallel_for(lanes, 1, lane);
    b.pending_roots.clear();
    for (auto& [k, f] : file)
      if (k.level <= b.part_level) b.pending_roots[k] = f;
  }
  if (b.part_level > 0) return;  // the part roots stay raw: write_part keeps them for the merge
  for (auto& [k, f] : b.pending_roots) {
    std::vector<TilePoint> pts;
    {
      Profiler::Scope read(&b.prof, Step::ReadDecode);
      pts = read_points(f);
      read.add_bytes(pts.size() * sizeof(TilePoint));
    }
    write_content(b, k, pts);
    fs::remove(f);
  }
  b.pending_roots.clear();
}

}  // namespace stipple::tiler::detail
