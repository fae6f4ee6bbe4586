// `stipple pointlets`: organise LAS/LAZ/COPC files into a pointlet cache (seed 002, III-A) and
// report how compact the pointlets are (the metrics of its Table I).
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <memory>
#include <string>

#include <nlohmann/json.hpp>

#include "stipple/app/commands.hpp"
#include "stipple/core/atomic_file.hpp"
#include "stipple/core/error.hpp"
#include "stipple/core/memory.hpp"
#include "stipple/pointcloud/pointlets.hpp"
#include "stipple/scene/scene.hpp"
#include "stipple/tiler/tiler.hpp"

namespace stipple::app {

void add_pointlets_command(CLI::App& cli) {
  struct Args {
    std::vector<std::string> inputs;
    std::string cache_dir, order = "hilbert", memory, json;
    pc::PointletBuildOptions options;
    bool rebuild = false, stats = false;
  };
  auto args = std::make_shared<Args>();
  auto* cmd = cli.add_subcommand(
      "pointlets",
      "Sort LAS/LAZ/COPC files into a pointlet cache (reused by later runs while the inputs are "
      "unchanged) and print the pointlets' extent metrics");
  cmd->add_option("inputs", args->inputs,
                  "Input .las/.laz files and folders of them (a survey's tiles: one cache)")
      ->required()
      ->check(CLI::ExistingPath);
  cmd->add_option("--cache", args->cache_dir,
                  "Folder of the cache (default: beside the first input, else ~/.cache/stipple)");
  cmd->add_option("--pointlets", args->options.pointlets,
                  "m of k = 2^floor(log2(n / m)): about how many pointlets")
      ->check(CLI::Range(uint64_t(1), uint64_t(1) << 31))
      ->capture_default_str();
  cmd->add_option("--order", args->order, "hilbert or morton")
      ->check(CLI::IsMember({"hilbert", "morton"}))
      ->capture_default_str();
  cmd->add_option("--host-memory", args->memory,
                  "Memory for sorting (larger inputs: sorted runs on disk, merged; default: what "
                  "render and view give the build, an eighth of RAM up to 4G)");
  cmd->add_option("--threads", args->options.threads, "Sorting threads (default: all cores)");
  cmd->add_flag("--rebuild", args->rebuild, "Build the cache even if a current one exists");
  cmd->add_flag("--stats", args->stats,
                "Print the build's phases (read, sort, merge, encode, write) in seconds");
  cmd->add_option("--json", args->json, "Write the figures as JSON");
  cmd->callback([args] {
    pc::PointletBuildOptions o = args->options;
    o.order = args->order == "morton" ? pc::SpatialOrder::Morton : pc::SpatialOrder::Hilbert;
    // render and view build with half their host budget (a quarter of RAM), at most 4G.
    const long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGE_SIZE);
    const uint64_t ram = pages > 0 && page > 0 ? uint64_t(pages) * uint64_t(page) : 0;
    o.memory_budget = !args->memory.empty() ? parse_size(args->memory)
                      : ram > 0             ? std::min<uint64_t>(ram / 8, uint64_t(4) << 30)
                                            : uint64_t(1) << 30;
    std::vector<std::filesystem::path> inputs;
    for (const std::string& in : scene::expand_input_folders(args->inputs)) inputs.push_back(in);
    const auto path = pc::pointlet_cache_path(inputs, args->cache_dir, o);
    if (args->rebuild) std::filesystem::remove(path);
    bool built = false;
    pc::PointletBuildStats stats;
    pc::PointletCache cache = pc::open_pointlet_cache(inputs, args->cache_dir, o, &built, &stats);
    const auto& info = cache.info();
    const pc::PointletMetrics m = pc::pointlet_metrics(cache.pointlets());
    if (built)
      std::printf("built %s: %llu points in %.2f s (%.2f M points/s, %llu sort run%s)\n",
                  path.string().c_str(), static_cast<unsigned long long>(stats.points),
                  stats.seconds, double(stats.points) / std::max(stats.seconds, 1e-9) / 1e6,
                  static_cast<unsigned long long>(stats.runs), stats.runs == 1 ? "" : "s");
    else
      std::printf("reused %s (the inputs are unchanged)\n", path.string().c_str());
    if (built && args->stats) std::printf("%s\n", pc::describe_build_phases(stats).c_str());
    std::printf(
        "%llu pointlets of k = %llu points (%s order); extent max %.3f, mean %.3f, std dev "
        "%.3f; mean squareness %.3f\n",
        static_cast<unsigned long long>(info.pointlet_count),
        static_cast<unsigned long long>(info.pointlet_points),
        info.order == pc::SpatialOrder::Morton ? "Morton" : "Hilbert", m.max_extent, m.mean_extent,
        m.stddev_extent, m.mean_squareness);
    if (!args->json.empty()) {
      nlohmann::json j;
      j["cache"] = path.string();
      j["built"] = built;
      j["points"] = info.point_count;
      j["pointlets"] = info.pointlet_count;
      j["pointlet_points"] = info.pointlet_points;
      j["order"] = info.order == pc::SpatialOrder::Morton ? "morton" : "hilbert";
      j["max_extent"] = m.max_extent;
      j["mean_extent"] = m.mean_extent;
      j["stddev_extent"] = m.stddev_extent;
      j["mean_squareness"] = m.mean_squareness;
      if (built) {
        j["build_seconds"] = stats.seconds;
        j["read_seconds"] = stats.read_seconds;
        j["sort_seconds"] = stats.sort_seconds;
        j["merge_seconds"] = stats.merge_seconds;
        j["encode_seconds"] = stats.encode_seconds;
        j["write_seconds"] = stats.write_seconds;
        j["write_wait_seconds"] = stats.write_wait_seconds;
        j["run_bytes"] = stats.run_bytes;
        j["run_disk_bytes"] = stats.run_disk_bytes;
        j["run_read_seconds"] = stats.run_read_seconds;
        j["runs"] = stats.runs;
        j["peak_run_bytes"] = stats.peak_run_bytes;
      }
      write_file_atomically(args->json, j.dump(2) + "\n");
    }
  });
}

}  // namespace stipple::app
