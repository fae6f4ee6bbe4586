// The tiler pipeline (Potree 2 / Entwine style, written for stipple), one phase a file:
//  1. headers: source CRS of each input -> ECEF (PROJ), one local ENU frame for the tileset,
//     the octree cube from the header boxes (densely sampled through the transform, padded)
//     (tiler_input);
//  2. counting pass: every point is transformed and counted in a grid at level Lc (<= 128^3)
//     (tiler_input);
//  3. chunking: the count pyramid is cut top-down into the largest octree nodes holding at
//     most `chunk_points` (sized from --max-memory and the thread count) (tiler_chunks);
//  4. distribution pass: points are transformed again and appended to one temporary file per
//     chunk (raw TilePoint records), or kept in memory (tiler_chunks, tiler_input);
//  5. indexing: chunks in parallel on the pool; each builds its subtree top-down: a node takes a
//     grid subsample at its level's spacing, the rest go to its 8 children, a node of at most
//     `max_node_points` keeps everything (leaf). Every point lands in exactly one node
//     (tiler_index; content files: tiler_content);
//  6. upper levels: from the deepest chunk roots up, a parent subsamples the union of its
//     children's points at its spacing; the selected points move up (additive refinement)
//     (tiler_upper);
//  7. tileset.json (tiler_tileset), or a part's part.json (tiler_parts), then
//     DIR.partial-XXXXXX is renamed to DIR.
// Spacing halves per level; geometricError = spacing of the tile's level (factor 1: the point
// spacing the tile shows, which is what a client hides by not refining; CesiumJS's point
// attenuation reads it the same way).
// This file only sequences the phases over one Build (tiler_build.hpp), and the merge of a
// split tiling over the parts (tiler_parts) the same way.
#include "stipple/tiler/tiler.hpp"

#include <stdlib.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <thread>

#include <nlohmann/json.hpp>

#include "stipple/core/error.hpp"
#include "stipple/core/log.hpp"
#include "tiler_build.hpp"
#include "tiler_chunks.hpp"
#include "tiler_index.hpp"
#include "tiler_input.hpp"
#include "tiler_parts.hpp"
#include "tiler_tileset.hpp"
#include "tiler_upper.hpp"

namespace stipple::tiler {

namespace detail {

namespace {

// Ends the phase under way (logging its time) and starts `next` (none: the run is over).
void phase(Build& b, const char* next) {
  auto now = std::chrono::steady_clock::now();
  if (!b.phase_name.empty())
    STIPPLE_INFO("tile: phase {:<30} {:8.3f} s", b.phase_name,
                 std::chrono::duration<double>(now - b.phase_start).count());
  b.phase_start = now;
  b.phase_name = next ? next : "";
  if (next)
    b.prof.phase(next);
  else
    b.prof.finish();
}

unsigned start_pool(Build& b) {
  unsigned threads =
      b.opt.threads ? b.opt.threads : std::max(1u, std::thread::hardware_concurrency());
  b.pool = std::make_unique<ThreadPool>(threads);
  return threads;
}

// The output is built in DIR.partial-XXXXXX beside it (removed unless the run commits), with
// its temporary files in .tmp.
fs::path begin_output(Build& b, const std::string& output) {
  fs::path out = fs::absolute(output).lexically_normal();
  if (out.filename().empty()) out = out.parent_path();
  if (fs::exists(out) && !b.opt.force) fail("{} exists; pass --force to replace it", out.string());
  fs::path parent = out.parent_path();
  if (!fs::is_directory(parent)) fail("{}: no such directory", parent.string());
  std::string templ = (parent / (out.filename().string() + ".partial-XXXXXX")).string();
  if (!::mkdtemp(templ.data()))
    fail("cannot create a directory beside {} ({})", out.string(), std::strerror(errno));
  b.partial = std::make_unique<PartialDir>();
  b.partial->path = templ;
  b.dir = b.partial->path;
  b.tmp = b.dir / ".tmp";
  fs::create_directories(b.tmp);
  fs::create_directories(b.dir / "tiles");
  return out;
}

TileStats commit(Build& b, const fs::path& out, std::chrono::steady_clock::time_point start) {
  // Commit: the finished directory replaces the output in one rename.
  if (fs::exists(out)) {
    fs::path old = out;
    old += fmt::format(".old-{}", ::getpid());
    fs::rename(out, old);
    fs::rename(b.dir, out);
    fs::remove_all(old);
  } else {
    fs::rename(b.dir, out);
  }
  b.partial->committed = true;
  phase(b, nullptr);

  TileStats stats;
  stats.points = b.total_points;
  stats.chunks = b.chunks.size();
  stats.root_spacing = b.root_spacing;
  for (auto& [k, info] : b.nodes) {
    stats.tiles += info.points > 0;
    stats.depth = std::max(stats.depth, k.level);
  }
  stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  stats.threads = b.pool ? b.pool->size() : 0;
  stats.phases = b.prof.phases();
  for (size_t s = 0; s < step_count; ++s) stats.steps.push_back(b.prof.step(Step(s)));
  return stats;
}

TileStats run_tiling(Build& b) {
  auto start = std::chrono::steady_clock::now();
  b.phase_start = start;
  phase(b, "headers, frame, cube");
  plan_part(b);
  const fs::path out = begin_output(b, b.opt.output);
  open_inputs(b);
  make_frame_and_cube(b);
  const unsigned threads = start_pool(b);
  b.prof.attach(*b.pool, b.opt.sample_threads);
  plan_budget(b, threads);
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
    const bool reread = !b.in_memory && std::none_of(b.inputs.begin(), b.inputs.end(),
                                                     [](auto& in) { return in.header.compressed; });
    phase(b, reread ? "read+decode+transform+count" : "read+decode+transform+stage+count");
    std::vector<std::atomic<uint32_t>> counts(size_t(1) << (3 * b.count_level));
    const fs::path staged = b.tmp / "staged.bin";
    const uint64_t staged_points = read_and_count(b, reread, counts, staged);
    phase(b, "plan chunks");
    plan_chunks(b, counts);
    phase(b, reread ? "read+decode+transform+distribute" : "distribute");
    if (b.in_memory) {
      distribute_in_memory(b, staged_points);
      b.staged_mem.reset();
    } else if (reread) {
      reread_and_distribute(b);
    } else {
      distribute(b, staged, staged_points);
      fs::remove(staged);
    }
    if (!b.in_memory) flush_chunk_buffers(b);
    std::vector<int32_t>().swap(b.cell_chunk);
    phase(b, "split oversized chunks");
  }
  check_distribution(b);
  split_oversized_chunks(b);
  phase(b, "index+sample+encode+write");
  index_chunks(b);
  phase(b, "upper levels");
  build_upper_levels(b);
  b.index_progress->finish();
  phase(b, b.part_level > 0 ? "part.json" : "tileset.json");
  uint64_t kept_for_merge = 0;
  for (auto& [k, f] : b.pending_roots) kept_for_merge += fs::file_size(f) / sizeof(TilePoint);
  if (b.written + kept_for_merge != b.total_points)
    fail("internal error: {} points written, {} read", b.written + kept_for_merge, b.total_points);
  if (b.part_level > 0)
    write_part(b);
  else
    write_tileset(b);
  fs::remove_all(b.tmp);
  phase(b, "commit");
  return commit(b, out, start);
}

TileStats run_merge(Build& b, const std::vector<nlohmann::json>& parts,
                    const std::vector<fs::path>& dirs) {
  const auto start = std::chrono::steady_clock::now();
  b.phase_start = start;
  phase(b, "read parts, link part tiles");
  settings_from_part(b, parts.front());
  const fs::path out = begin_output(b, b.opt.output);
  start_pool(b);
  link_parts(b, parts, dirs);
  phase(b, "upper levels");
  b.index_progress = std::make_unique<Progress>("upper levels", b.total_points);
  build_upper_levels(b);
  b.index_progress->finish();
  phase(b, "tileset.json");
  check_merged(b);
  write_tileset(b);
  fs::remove_all(b.tmp);
  phase(b, "commit");
  return commit(b, out, start);
}

}  // namespace

}  // namespace detail

TileStats build_tileset(const TileOptions& options) {
  detail::Build build(options);
  return detail::run_tiling(build);
}

TileStats merge_parts(const MergeOptions& options) {
  try {
    const detail::PartSet set = detail::read_parts(options);
    detail::Build build(set.options);
    return detail::run_merge(build, set.parts, set.dirs);
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
