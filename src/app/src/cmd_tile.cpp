// `stipple tile`: LAS/LAZ inputs -> one 3D Tiles tileset (glb for 1.1, pnts for 1.0), out of core;
// Gaussian splat inputs (.ply with splat properties, .spz, .splat, ...) -> a splat tileset with
// level of detail (tiler/splat_tiler.hpp).
#include <cstdio>
#include <memory>
#include <tuple>

#include "stipple/app/commands.hpp"
#include "stipple/app/web_page.hpp"
#include "stipple/core/atomic_file.hpp"
#include "stipple/core/error.hpp"
#include "stipple/core/memory.hpp"
#include "stipple/io/splat_readers.hpp"
#include "stipple/tiler/splat_tiler.hpp"
#include "stipple/tiler/tiler.hpp"

namespace stipple::app {

void add_tile_command(CLI::App& cli) {
  struct Args {
    tiler::TileOptions options;
    std::string format = "glb", memory = "2G", subset;
    tiler::MergeOptions merge;
    std::string merge_memory = "2G";
    bool profile = false;
    bool page = false;
    std::string stats;
    std::string splat_compression = "spz";
    size_t max_leaf_splats = 65536;
  };
  auto args = std::make_shared<Args>();
  auto* cmd = cli.add_subcommand(
      "tile",
      "Build a 3D Tiles tileset from LAS/LAZ files (octree, additive refinement) or from Gaussian "
      "splat files (octree of merged splats, replacement refinement)");
  cmd->add_option("inputs", args->options.inputs, "Input .las/.laz files, or splat files");
  cmd->add_option("-o,--output", args->options.output, "Output directory");
  cmd->add_option("--format", args->format, "glb (3D Tiles 1.1) or pnts (3D Tiles 1.0)")
      ->check(CLI::IsMember({"glb", "pnts"}))
      ->capture_default_str();
  cmd->add_option("--crs", args->options.crs,
                  "Source CRS (e.g. EPSG:2992), overriding the inputs' own; required for inputs "
                  "without one");
  cmd->add_option("--spacing", args->options.spacing,
                  "Root point spacing in metres (default: cube edge / 128); halves per level");
  cmd->add_option("--max-memory", args->memory, "Memory budget, e.g. 2G, 512M")
      ->capture_default_str();
  cmd->add_option("--threads", args->options.threads, "Worker threads (default: all cores)");
  cmd->add_option("--max-node-points", args->options.max_node_points, "Tile size cap")
      ->check(CLI::Range(size_t(1000), size_t(10'000'000)))
      ->capture_default_str();
  cmd->add_option("--compress", args->options.compression,
                  "none, meshopt (glb: EXT_meshopt_compression) or draco (pnts: "
                  "3DTILES_draco_point_compression)")
      ->check(CLI::IsMember({"none", "meshopt", "draco"}))
      ->capture_default_str();
  cmd->add_option("--splat-compression", args->splat_compression,
                  "Splat inputs: spz (KHR_gaussian_splatting_compression_spz_2, what CesiumJS "
                  "reads) or none (float attributes)")
      ->check(CLI::IsMember({"spz", "none"}))
      ->capture_default_str();
  cmd->add_option("--max-leaf-splats", args->max_leaf_splats,
                  "Splat inputs: the most splats a leaf tile holds")
      ->check(CLI::Range(size_t(16), size_t(1'000'000'000)))
      ->capture_default_str();
  cmd->add_flag("--implicit", args->options.implicit,
                "Write 3D Tiles 1.1 implicit tiling (an octree of subtree files) instead of "
                "listing every tile in tileset.json");
  cmd->add_option("--subtree-levels", args->options.subtree_levels,
                  "Implicit tiling: levels in one subtree file")
      ->check(CLI::Range(1, 16))
      ->capture_default_str();
  cmd->add_flag("--force", args->options.force, "Replace an existing output directory");
  cmd->add_flag("--page", args->page,
                "Copy the web viewer (scripts/build-web.sh) next to tileset.json, with an "
                "index.html that opens it: the folder can be served statically and opened by link");
  cmd->add_flag("--profile", args->profile,
                "Print a table of the phases (wall, CPU per thread, system time, bytes read and "
                "written, page faults, time with at most one thread runnable) and of the steps");
  cmd->add_option("--stats", args->stats,
                  "Write the run's stats and its per-phase profile as JSON to this file");
  cmd->add_option("--subset", args->subset,
                  "Split tiling: tile only part I of N (N a power of 4 or 8) of the root cube, "
                  "every input read; the output is a part for `stipple tile merge`");
  auto* merge = cmd->add_subcommand(
      "merge",
      "Merge the parts of a split tiling (tile --subset I/N, every I) into one tileset: the "
      "levels above the parts are built from the parts' roots");
  merge->add_option("parts", args->merge.parts, "Part directories (all N)")->required();
  merge->add_option("-o,--output", args->merge.output, "Output directory")->required();
  merge->add_option("--max-memory", args->merge_memory, "Memory budget, e.g. 2G, 512M")
      ->capture_default_str();
  merge->add_option("--threads", args->merge.threads, "Worker threads (default: all cores)");
  merge->add_flag("--force", args->merge.force, "Replace an existing output directory");
  merge->callback([args] {
    args->merge.max_memory = parse_size(args->merge_memory);
    tiler::TileStats s = tiler::merge_parts(args->merge);
    std::printf("merged %zu parts: %llu points in %llu tiles (depth %d) in %.2f s\n",
                args->merge.parts.size(), static_cast<unsigned long long>(s.points),
                static_cast<unsigned long long>(s.tiles), s.depth, s.seconds);
  });
  cmd->callback([args, merge] {
    if (merge->parsed()) return;
    if (args->options.inputs.empty()) throw CLI::RequiredError("inputs");
    if (args->options.output.empty()) throw CLI::RequiredError("--output");
    if (args->page && !args->subset.empty())
      fail("--page is for a whole tileset, not a part (--subset): merge the parts first");
    // Found before tiling: a missing viewer is said at once, not after the work.
    if (args->page) find_web_viewer();
    size_t splat_inputs = 0;
    for (const std::string& in : args->options.inputs) splat_inputs += io::is_splat_path(in);
    if (splat_inputs > 0) {
      if (splat_inputs != args->options.inputs.size())
        fail("tile: splat files and point clouds cannot be tiled together");
      if (!args->subset.empty() || args->options.implicit || args->format != "glb")
        fail("tile: --subset, --implicit and --format pnts are for point clouds, not splats");
      // The web viewer streams tilesets of points only: its page would not draw this one.
      if (args->page)
        fail("tile: --page is for point tilesets; the web viewer draws no splat tilesets yet");
      tiler::SplatTileOptions o;
      o.inputs = args->options.inputs;
      o.output = args->options.output;
      o.compression = args->splat_compression == "none" ? tiler::SplatCompression::None
                                                        : tiler::SplatCompression::Spz;
      o.max_leaf_splats = args->max_leaf_splats;
      o.max_memory = parse_size(args->memory);
      o.threads = args->options.threads;
      o.force = args->options.force;
      const tiler::SplatTileStats s = tiler::build_splat_tileset(o);
      std::printf(
          "tiled %llu splats (SH degree %d) into %llu tiles (%llu leaves, depth %d, %zu chunks; "
          "%llu merged splats in the inner tiles), %.1f MB of glb, in %.2f s\n",
          static_cast<unsigned long long>(s.splats), s.sh_degree,
          static_cast<unsigned long long>(s.tiles), static_cast<unsigned long long>(s.leaves),
          s.depth, s.chunks, static_cast<unsigned long long>(s.merged_splats),
          double(s.bytes) / 1e6, s.seconds);
      return;
    }
    if (!args->subset.empty())
      std::tie(args->options.subset_index, args->options.subset_count) =
          tiler::parse_subset(args->subset);
    args->options.format = args->format == "pnts" ? tiler::Format::Pnts : tiler::Format::Glb;
    args->options.max_memory = parse_size(args->memory);
    args->options.sample_threads = args->profile || !args->stats.empty();
    tiler::TileStats s = tiler::build_tileset(args->options);
    std::printf(
        "tiled %llu points into %llu tiles (depth %d, %zu chunks, root spacing %.3f m) in "
        "%.2f s: %.2f M points/s\n",
        static_cast<unsigned long long>(s.points), static_cast<unsigned long long>(s.tiles),
        s.depth, s.chunks, s.root_spacing, s.seconds, double(s.points) / s.seconds / 1e6);
    if (args->profile) std::printf("\n%s", tiler::profile_table(s).c_str());
    if (!args->stats.empty()) write_file_atomically(args->stats, tiler::stats_json(s));
    if (args->page) {
      const auto viewer = write_web_page(args->options.output);
      std::printf("web viewer copied from %s: serve %s and open index.html\n",
                  viewer.string().c_str(), args->options.output.c_str());
    }
  });
}

}  // namespace stipple::app
