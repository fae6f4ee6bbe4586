// `stipple info`: what a point-cloud or splat file holds, or what the GPU offers.
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <set>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "stipple/app/commands.hpp"
#include "stipple/core/error.hpp"
#include "stipple/io/content_summary.hpp"
#include "stipple/io/copc.hpp"
#include "stipple/io/fetch.hpp"
#include "stipple/io/las.hpp"
#include "stipple/io/source.hpp"
#include "stipple/io/splat_readers.hpp"
#include "stipple/io/tileset.hpp"
#include "stipple/renderer/gpu.hpp"
#include "stipple/tiles3d/render_load.hpp"

namespace stipple::app {
namespace {

struct InfoArgs {
  std::vector<std::string> inputs;
  bool gpu = false;
  bool json = false;
  bool vlrs = false;
  std::string backend;
  size_t max_tiles = 1'000'000;  // tilesets: the whole tree is read up to this many tiles
};

// -0 (some writers store it for a zero offset) printed as 0.
glm::dvec3 no_negative_zero(glm::dvec3 v) {
  for (int i = 0; i < 3; ++i)
    if (v[i] == 0.0) v[i] = 0.0;
  return v;
}

nlohmann::json header_json(const io::LasHeader& h) {
  return nlohmann::json::parse(io::las_header_json(h));
}

void print_header(const io::LasHeader& h, bool vlrs) {
  std::printf("%s\n", h.path.c_str());
  std::printf("  LAS %u.%u, point format %u (%u bytes/point)%s%s\n", h.version_major,
              h.version_minor, h.point_format, h.point_record_length,
              h.compressed ? ", LAZ compressed" : "", h.copc ? ", COPC" : "");
  std::printf("  points:     %llu\n", static_cast<unsigned long long>(h.point_count));
  const glm::dvec3 lo = no_negative_zero(h.min), hi = no_negative_zero(h.max);
  std::printf("  bounds min: %.6f %.6f %.6f\n", lo.x, lo.y, lo.z);
  std::printf("  bounds max: %.6f %.6f %.6f\n", hi.x, hi.y, hi.z);
  // Exactly (the shortest text that reads back as the same double): 6 significant digits made
  // X and Y scales of 0.001 and 0.0010000001 look the same.
  const glm::dvec3 scale = no_negative_zero(h.scale), offset = no_negative_zero(h.offset);
  std::printf("  scale:      %s\n", fmt::format("{} {} {}", scale.x, scale.y, scale.z).c_str());
  std::printf("  offset:     %s\n", fmt::format("{} {} {}", offset.x, offset.y, offset.z).c_str());
  std::printf("  CRS:        %s\n", h.crs.describe().c_str());
  if (const std::string problem = io::geographic_bounds_problem(h); !problem.empty())
    std::printf("  problem:    %s\n", problem.c_str());
  std::string attrs = "intensity, returns, classification, scan angle";
  if (h.has_gps_time) attrs += ", GPS time";
  if (h.has_rgb && h.rgb_uniform)
    attrs +=
        fmt::format(", RGB (one colour, {},{},{}, in the first {} points)", (*h.rgb_uniform)[0],
                    (*h.rgb_uniform)[1], (*h.rgb_uniform)[2], h.rgb_probed);
  else if (h.has_rgb)
    attrs += fmt::format(", RGB ({}-bit values)", h.rgb_bits);
  if (h.has_nir) attrs += ", NIR";
  if (h.has_waveform) attrs += ", waveform packets";
  if (h.extra_bytes_per_point) {
    std::string described;
    size_t covered = 0;
    for (const auto& e : h.extra_bytes) {
      described += fmt::format("{}{} ({})", described.empty() ? "" : ", ",
                               e.name.empty() ? "unnamed" : e.name, io::extra_bytes_type_name(e));
      covered += e.size;
    }
    if (h.extra_bytes.empty())
      attrs += fmt::format(", {} extra bytes (undescribed)", h.extra_bytes_per_point);
    else if (covered != h.extra_bytes_per_point)
      attrs += fmt::format(", {} extra bytes (described: {}, {} bytes)", h.extra_bytes_per_point,
                           described, covered);
    else
      attrs += ", extra bytes: " + described;
  }
  std::printf("  attributes: %s\n", attrs.c_str());
  // System identifier and generating software, whichever are filled in.
  std::string software = h.system_identifier;
  if (!h.generating_software.empty())
    software += (software.empty() ? "" : " / ") + h.generating_software;
  std::printf("  software:   %s\n", software.empty() ? "(not given)" : software.c_str());
  std::printf("  VLRs:       %zu, EVLRs: %zu\n", h.vlrs.size(), h.evlrs.size());
  if (vlrs) {
    for (const auto& v : h.vlrs)
      std::printf("    VLR  %-16s %5u %7zu bytes  %s\n", v.user_id.c_str(), v.record_id,
                  v.data.size(), v.description.c_str());
    for (const auto& v : h.evlrs)
      std::printf("    EVLR %-16s %5u %7zu bytes  %s\n", v.user_id.c_str(), v.record_id,
                  v.data.size(), v.description.c_str());
  }
}

void print_gpu(const std::string& backend, bool json) {
  gpu::ContextOptions options;
  options.backend = backend;
  auto ctx = gpu::create_context(options);
  const auto& d = ctx->description;
  if (json) {
    nlohmann::json j;
    j["backend"] = d.backend;
    j["adapter"] = {
        {"vendor", d.vendor},           {"architecture", d.architecture}, {"device", d.device},
        {"description", d.description}, {"graphics_api", d.graphics_api}, {"type", d.adapter_type},
        {"vendor_id", d.vendor_id},     {"device_id", d.device_id}};
    for (const auto& [name, value] : gpu::limit_list(ctx->limits)) j["limits"][name] = value;
    for (auto f : ctx->adapter_features) j["features"].push_back(gpu::feature_name(f));
    std::printf("%s\n", j.dump(2).c_str());
    return;
  }
  std::printf("WebGPU implementation: %s\n", d.backend.c_str());
  std::printf("adapter:  %s (%s)\n", d.device.c_str(), d.adapter_type.c_str());
  std::printf("  vendor %s (0x%04x), device 0x%04x, architecture %s\n", d.vendor.c_str(),
              d.vendor_id, d.device_id, d.architecture.c_str());
  std::printf("  graphics API: %s; driver: %s\n", d.graphics_api.c_str(), d.description.c_str());
  std::printf("limits (device created with the adapter's own):\n");
  for (const auto& [name, value] : gpu::limit_list(ctx->limits))
    std::printf("  %-44s %llu\n", name.c_str(), static_cast<unsigned long long>(value));
  std::printf("features (%zu):\n", ctx->adapter_features.size());
  for (auto f : ctx->adapter_features)
    std::printf("  %s%s\n", gpu::feature_name(f).c_str(), ctx->has_feature(f) ? " (enabled)" : "");
}

// A tileset's shape: depth, tiles, content types, declared points (from loading every content
// would be too much for a summary: points are counted for the tiles a framing camera selects).
// Streaming reads external tilesets and subtrees only where a view needs them; a summary wants
// the whole tree, so it reads every one, up to `max_tiles` tiles.
nlohmann::json tileset_json(const std::string& uri, size_t max_tiles) {
  io::TilesetOptions options;
  io::Tileset ts = io::load_tileset(uri, options);
  const bool complete = io::expand_all(
      ts, [&](const std::string& u) { return io::fetch(u, options.fetch); }, options, max_tiles);
  if (!complete)
    ts.warnings.push_back(
        fmt::format("the tile tree was read up to {} tiles (--max-tiles): "
                    "external tilesets or subtrees below them are not counted",
                    ts.tiles.size()));
  nlohmann::json j;
  j["complete"] = complete;
  j["uri"] = uri;
  j["version"] = ts.version;
  j["geometric_error"] = ts.geometric_error;
  j["tiles"] = ts.tiles.size();
  uint32_t depth = 0;
  size_t contents = 0;
  std::map<std::string, size_t> types;
  for (const auto& t : ts.tiles) {
    depth = std::max(depth, t.depth);
    contents += t.contents.size();
    for (const auto& c : t.contents) {
      std::string p = io::uri_path(c);
      size_t dot = p.rfind('.');
      types[dot == std::string::npos ? "?" : p.substr(dot + 1)]++;
    }
  }
  j["depth"] = depth + 1;
  j["contents"] = contents;
  j["content_types"] = types;
  // Totals from the tile headers (no point decoded), for the tiles read (--max-tiles caps it).
  std::vector<std::string> uris;
  for (size_t i = 0; i < ts.tiles.size() && i < max_tiles; ++i)
    uris.insert(uris.end(), ts.tiles[i].contents.begin(), ts.tiles[i].contents.end());
  j["points_complete"] = complete && ts.tiles.size() <= max_tiles;
  const io::ContentTotals totals = io::summarize_contents(
      uris, [&](const std::string& u) { return io::fetch(u, options.fetch); });
  j["points"] = totals.points;
  j["contents_by_type"] = totals.by_type;
  j["contents_not_drawn"] = totals.not_drawn;
  std::vector<std::string> content_warnings;
  for (const auto& [type, n] : totals.not_drawn)
    content_warnings.push_back(fmt::format("{} of {} contents are {}, which stipple does not draw",
                                           n, totals.contents, io::describe_content_type(type)));
  if (totals.other_primitives)
    content_warnings.push_back(fmt::format(
        "{} glTF primitives are meshes or lines, which stipple does not draw (points only)",
        totals.other_primitives));
  j["content_warnings"] = content_warnings;
  j["content_errors"] = totals.errors;
  ts.warnings.insert(ts.warnings.end(), content_warnings.begin(), content_warnings.end());
  j["external_tilesets"] = ts.external_tilesets;
  j["implicit"] = ts.implicit;
  j["subtrees"] = ts.subtrees;
  j["warnings"] = ts.warnings;
  j["errors"] = ts.errors;
  auto loaded = tiles3d::load_tileset_for_render(uri, {});
  j["points_selected_for_default_view"] = loaded.cloud.point_count;
  j["tiles_selected_for_default_view"] = loaded.tiles_rendered;
  j["tile_errors"] = loaded.errors.size();
  // Each kind of tile problem once, with how many tiles had it.
  nlohmann::json problems = nlohmann::json::array();
  std::map<std::string, size_t> index;
  auto add = [&](const tiles3d::TileError& e, const char* severity) {
    const std::string kind(tiles3d::tile_problem_kind(e.message));
    auto [it, fresh] = index.try_emplace(kind, problems.size());
    if (fresh) problems.push_back({{"severity", severity}, {"message", e.message}, {"tiles", 0}});
    problems[it->second]["tiles"] = problems[it->second]["tiles"].get<size_t>() + 1;
  };
  for (const auto& e : loaded.errors) add(e, "error");
  for (const auto& w : loaded.warnings) add(w, "warning");
  j["tile_problems"] = problems;
  // What `render` would refuse: a default view whose tiles hold no points.
  if (loaded.cloud.point_count == 0) {
    const bool read = loaded.stats.loads_completed > 0 || !loaded.errors.empty();
    // (Content not drawn that the headers showed is not warned about again by the tiles.)
    const std::string why = !loaded.errors.empty()      ? loaded.errors.front().message
                            : !loaded.warnings.empty()  ? loaded.warnings.front().message
                            : !content_warnings.empty() ? content_warnings.front()
                                                        : std::string();
    j["problem"] = read ? fmt::format(
                              "nothing to render: the tiles in the default view hold no "
                              "points{}",
                              why.empty() ? "" : fmt::format(" ({})", why))
                        : "nothing to render: no tile with content is in the default view";
  }
  return j;
}

// A COPC file: its header, and its octree read page by page (every page, up to max_tiles nodes).
nlohmann::json copc_json(const std::string& uri, size_t max_tiles, io::LasHeader* header) {
  io::TilesetOptions options;
  io::Tileset ts = io::load_copc_tileset(uri, options);
  const bool complete = io::expand_all(
      ts, [&](const std::string& u) { return io::fetch(u, options.fetch); }, options, max_tiles);
  *header = ts.copc->header;
  nlohmann::json j = header_json(*header);
  const io::CopcInfo& info = ts.copc->info;
  nlohmann::json h;
  h["complete"] = complete;
  h["center"] = {info.center.x, info.center.y, info.center.z};
  h["halfsize"] = info.halfsize;
  h["spacing"] = info.spacing;
  h["pages"] = ts.subtrees;
  std::vector<uint64_t> nodes, points;
  uint64_t total = 0;
  for (const auto& t : ts.tiles) {
    if (t.depth >= nodes.size()) {
      nodes.resize(t.depth + 1);
      points.resize(t.depth + 1);
    }
    ++nodes[t.depth];
    for (const auto& c : t.contents) {
      const uint64_t n = std::strtoull(io::fragment_field(c, "points").c_str(), nullptr, 10);
      points[t.depth] += n;
      total += n;
    }
  }
  nlohmann::json levels = nlohmann::json::array();
  for (size_t d = 0; d < nodes.size(); ++d)
    levels.push_back({{"depth", d},
                      {"nodes", nodes[d]},
                      {"points", points[d]},
                      {"spacing", info.spacing / double(uint64_t(1) << d)}});
  h["levels"] = levels;
  h["nodes"] = ts.tiles.size();
  h["points"] = total;
  h["errors"] = ts.errors;
  if (complete && total != header->point_count)
    h["errors"].push_back(fmt::format("the hierarchy holds {} points, the header says {}", total,
                                      header->point_count));
  j["hierarchy"] = h;
  return j;
}

void print_copc_hierarchy(const nlohmann::json& h) {
  std::printf("  hierarchy:  %zu nodes in %u pages, %zu levels, %llu points%s; root spacing %g\n",
              h["nodes"].get<size_t>(), h["pages"].get<uint32_t>(), h["levels"].size(),
              static_cast<unsigned long long>(h["points"].get<uint64_t>()),
              h["complete"].get<bool>() ? "" : " (read up to --max-tiles nodes)",
              h["spacing"].get<double>());
  for (const auto& l : h["levels"])
    std::printf("    level %2zu: %8llu nodes %12llu points, spacing %g\n", l["depth"].get<size_t>(),
                static_cast<unsigned long long>(l["nodes"].get<uint64_t>()),
                static_cast<unsigned long long>(l["points"].get<uint64_t>()),
                l["spacing"].get<double>());
  for (const auto& e : h["errors"]) std::printf("  error: %s\n", e.get<std::string>().c_str());
}

// A splat file: format, count, SH degree and the bounds of the splat centres (in the source's
// frame: SplatSet::transform applied).
// A .glb is read as glTF splats (KHR_gaussian_splatting).
nlohmann::json splat_json(const std::string& input) {
  const io::SplatSet s = io::uri_path(input).ends_with(".glb")
                             ? io::decode_splats_glb(io::fetch(input), input)
                             : io::read_splats(input);
  glm::dvec3 lo(0.0), hi(0.0);
  for (size_t i = 0; i < s.size(); ++i) {
    const glm::dvec3 p(s.transform * glm::dvec4(glm::dvec3(s.positions[i]), 1.0));
    lo = i ? glm::min(lo, p) : p;
    hi = i ? glm::max(hi, p) : p;
  }
  nlohmann::json j;
  j["file"] = input;
  j["format"] = s.format;
  j["splats"] = s.size();
  j["sh_degree"] = s.sh_degree;
  lo = no_negative_zero(lo);
  hi = no_negative_zero(hi);
  j["bounds"] = {{"min", {lo.x, lo.y, lo.z}}, {"max", {hi.x, hi.y, hi.z}}};
  return j;
}

void print_splats(const nlohmann::json& j) {
  std::printf("%s\n", j["file"].get<std::string>().c_str());
  std::printf("  %s: %llu splats, SH degree %d\n", j["format"].get<std::string>().c_str(),
              static_cast<unsigned long long>(j["splats"].get<uint64_t>()),
              j["sh_degree"].get<int>());
  for (const char* end : {"min", "max"}) {
    const auto& b = j["bounds"][end];
    std::printf("  bounds %s: %.6f %.6f %.6f\n", end, b[0].get<double>(), b[1].get<double>(),
                b[2].get<double>());
  }
}

void run_info(const InfoArgs& args) {
  if (args.gpu) {
    print_gpu(args.backend, args.json);
    if (args.inputs.empty()) return;
  }
  if (args.inputs.empty()) fail("info: give a file, or --gpu");
  nlohmann::json all = nlohmann::json::array();
  for (const auto& input : args.inputs) {
    if (io::is_splat_path(input) || io::uri_path(input).ends_with(".glb")) {
      auto j = splat_json(input);
      if (args.json)
        all.push_back(j);
      else
        print_splats(j);
      continue;
    }
    const io::SourceFormat format = io::source_format(input);
    if (format == io::SourceFormat::Copc) {
      io::LasHeader header;
      auto j = copc_json(input, args.max_tiles, &header);
      if (args.json) {
        all.push_back(j);
      } else {
        print_header(header, args.vlrs);
        print_copc_hierarchy(j["hierarchy"]);
      }
      continue;
    }
    if (io::is_streamed(format)) {
      auto j = tileset_json(input, args.max_tiles);
      if (args.json) {
        all.push_back(j);
      } else {
        const std::string version = j["version"].get<std::string>();
        std::printf("%s\n  %s%s: %zu tiles, depth %u, %zu contents %s\n", input.c_str(),
                    version.rfind("1.", 0) == 0 ? "3D Tiles " : "", version.c_str(),
                    j["tiles"].get<size_t>(), j["depth"].get<uint32_t>(),
                    j["contents"].get<size_t>(), j["content_types"].dump().c_str());
        std::printf("  external tilesets: %u, implicit: %s, subtrees: %u, errors: %zu\n",
                    j["external_tilesets"].get<uint32_t>(),
                    j["implicit"].get<bool>() ? "yes" : "no", j["subtrees"].get<uint32_t>(),
                    j["errors"].size());
        if (!j["complete"].get<bool>())
          std::printf("  the tree was read up to %zu tiles (--max-tiles): counts are partial\n",
                      j["tiles"].get<size_t>());
        std::printf("  points:     %llu (declared by the tile headers%s)\n",
                    static_cast<unsigned long long>(j["points"].get<uint64_t>()),
                    j["points_complete"].get<bool>() ? "" : " of the first --max-tiles tiles");
        std::string by_type;
        for (const auto& [type, n] : j["contents_by_type"].items())
          by_type += fmt::format("{}{} {}", by_type.empty() ? "" : ", ", n.get<uint64_t>(), type);
        std::printf("  contents:   %s\n", by_type.empty() ? "none" : by_type.c_str());
        for (const auto& w : j["content_warnings"])
          std::printf("  warning: %s\n", w.get<std::string>().c_str());
        for (const auto& e : j["content_errors"])
          std::printf("  error: %s\n", e.get<std::string>().c_str());
        std::printf(
            "  points in the default view: %llu (%u tiles)\n",
            static_cast<unsigned long long>(j["points_selected_for_default_view"].get<uint64_t>()),
            j["tiles_selected_for_default_view"].get<uint32_t>());
        if (j.contains("problem"))
          std::printf("  problem: %s\n", j["problem"].get<std::string>().c_str());
        // The tree's own problems (external tilesets, subtrees), then the default view's tiles'
        // (which repeat the tree's problems the view ran into); the content warnings, printed
        // above, are among the tree's warnings too.
        std::set<std::string> said;
        for (const auto& w : j["content_warnings"]) said.insert(w.get<std::string>());
        for (const char* kind : {"warnings", "errors"})
          for (const auto& m : j[kind])
            if (said.insert(m.get<std::string>()).second)
              std::printf("  %s: %s\n", kind[0] == 'w' ? "warning" : "error",
                          m.get<std::string>().c_str());
        for (const auto& p : j["tile_problems"]) {
          if (said.count(p["message"].get<std::string>())) continue;
          const size_t tiles = p["tiles"].get<size_t>();
          std::printf("  %s: %s%s\n", p["severity"].get<std::string>().c_str(),
                      p["message"].get<std::string>().c_str(),
                      tiles > 1 ? fmt::format(" (and {} more tiles)", tiles - 1).c_str() : "");
        }
      }
      continue;
    }
    // Opening a reader also looks at the first points (8-bit colour detection).
    io::LasHeader header = io::LasReader(input).header();
    if (args.json)
      all.push_back(header_json(header));
    else
      print_header(header, args.vlrs);
  }
  if (args.json) std::printf("%s\n", (all.size() == 1 ? all[0] : all).dump(2).c_str());
}

}  // namespace

void add_info_command(CLI::App& cli) {
  auto args = std::make_shared<InfoArgs>();
  auto* cmd = cli.add_subcommand(
      "info", "Describe LAS/LAZ/COPC and splat files, tilesets, or the GPU (--gpu)");
  cmd->add_option("inputs", args->inputs, "Input files, tileset.json paths or URLs");
  cmd->add_flag("--gpu", args->gpu, "Print the WebGPU adapter, backend, limits and features");
  cmd->add_flag("--json", args->json, "Print JSON instead of text");
  cmd->add_flag("--vlrs", args->vlrs, "List every VLR and EVLR");
  cmd->add_option("--max-tiles", args->max_tiles,
                  "Tilesets: read external tilesets and subtrees up to this many tiles")
      ->check(CLI::Range(size_t(1), size_t(1) << 32))
      ->capture_default_str();
  cmd->add_option("--backend", args->backend, "WebGPU implementation for --gpu: dawn or wgpu")
      ->check(CLI::IsMember({"dawn", "wgpu", "wgpu-native"}));
  cmd->callback([args] { run_info(*args); });
}

}  // namespace stipple::app
