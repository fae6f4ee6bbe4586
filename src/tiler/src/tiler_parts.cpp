#include "tiler_parts.hpp"

#include <cmath>
#include <fstream>
#include <set>
#include <string>

#include "stipple/core/error.hpp"
#include "stipple/core/log.hpp"
#include "tiler_files.hpp"

namespace stipple::tiler {

std::pair<uint32_t, uint32_t> parse_subset(const std::string& text) {
  const size_t slash = text.find('/');
  uint64_t index = 0, count = 0;
  bool ok = slash != std::string::npos && slash > 0 && slash + 1 < text.size();
  for (size_t i = 0; ok && i < text.size(); ++i) {
    if (i == slash) continue;
    if (text[i] < '0' || text[i] > '9' || (i < slash ? index : count) > (1u << 30)) {
      ok = false;
      break;
    }
    uint64_t& v = i < slash ? index : count;
    v = v * 10 + uint64_t(text[i] - '0');
  }
  bool power = false;
  for (uint64_t v = 4; ok && v <= count; v *= 4) power |= v == count;
  for (uint64_t v = 8; ok && v <= count; v *= 8) power |= v == count;
  if (!ok || !power || index >= count)
    fail("--subset '{}' is not I/N with N a power of 4 or 8 (4, 8, 16, 64, ...) and 0 <= I < N",
         text);
  return {uint32_t(index), uint32_t(count)};
}

}  // namespace stipple::tiler

namespace stipple::tiler::detail {

namespace {

// Hard links where the file system allows (parts stay intact for a re-run), else copies. A
// file of that name from another part is refused, not replaced: two parts never hold one tile.
void link_or_copy(const fs::path& from, const fs::path& to, const fs::path& part) {
  std::error_code ec;
  if (fs::exists(fs::symlink_status(to, ec)))
    fail("{}: tile file {} is in another part too", part.string(), to.filename().string());
  fs::create_hard_link(from, to, ec);
  if (ec) fs::copy_file(from, to, fs::copy_options::none);
}

// Whether part.json has the shape write_part gives it: integers where integers are read (a
// double read as an integer out of its range would be undefined behaviour), numbers, strings
// and booleans elsewhere.
bool part_json_shape_ok(const nlohmann::json& p) {
  auto uints = [](const nlohmann::json& a, size_t from, size_t to) {
    for (size_t i = from; i < to; ++i)
      if (!a[i].is_number_unsigned()) return false;
    return true;
  };
  auto numbers = [](const nlohmann::json& a, size_t from, size_t to) {
    for (size_t i = from; i < to; ++i)
      if (!a[i].is_number()) return false;
    return true;
  };
  auto array_of = [](const nlohmann::json& a, size_t n) { return a.is_array() && a.size() == n; };
  if (!p.is_object()) return false;
  for (const char* key :
       {"subset", "level", "points", "inputs", "format", "compression", "implicit",
        "subtree_levels", "max_node_points", "cube", "root_spacing", "max_level", "precision",
        "rgb", "gps_time", "frame_origin", "nodes", "roots"})
    if (!p.contains(key)) return false;
  for (const char* key : {"level", "points", "subtree_levels", "max_node_points", "max_level"})
    if (!p[key].is_number_unsigned()) return false;
  if (!array_of(p["subset"], 2) || !uints(p["subset"], 0, 2)) return false;
  if (!array_of(p["cube"], 4) || !numbers(p["cube"], 0, 4)) return false;
  if (!array_of(p["frame_origin"], 3) || !numbers(p["frame_origin"], 0, 3)) return false;
  if (!p["root_spacing"].is_number() || !p["precision"].is_number()) return false;
  if (!p["nodes"].is_array() || !p["roots"].is_array() || !p["inputs"].is_array()) return false;
  for (const auto& n : p["nodes"])
    if (!array_of(n, 11) || !uints(n, 0, 5) || !numbers(n, 5, 11)) return false;
  for (const auto& r : p["roots"])
    if (!array_of(r, 5) || !uints(r, 0, 5)) return false;
  return p["subtree_levels"].get<uint64_t>() <= 16 && p["level"].get<uint64_t>() <= 30 &&
         p["max_level"].get<uint64_t>() <= 30;
}

// The numbers the merge computes with, in the ranges a tiling gives them: a cube of finite
// corner and an edge of 1 m to 10^8 m (make_frame_and_cube makes it at least 2 m), a root
// spacing between edge / 2^20 and 10^8 m, a positive finite precision and frame origin.
void check_part_ranges(const nlohmann::json& p, const fs::path& file) {
  const auto& c = p["cube"];
  const double edge = c[3].get<double>(), spacing = p["root_spacing"].get<double>(),
               precision = p["precision"].get<double>();
  bool finite = std::isfinite(precision);
  for (size_t i = 0; i < 3; ++i)
    finite = finite && std::isfinite(c[i].get<double>()) && std::abs(c[i].get<double>()) <= 1e9 &&
             std::isfinite(p["frame_origin"][i].get<double>());
  if (!finite || !(edge >= 1.0 && edge <= 1e8))
    fail("{}: cube [{}, {}, {}] of edge {} (or frame origin) is out of range (edge 1 m to 1e8 m)",
         file.string(), c[0].get<double>(), c[1].get<double>(), c[2].get<double>(), edge);
  if (!(spacing >= edge / double(1 << 20) && spacing <= 1e8))
    fail("{}: root spacing {} is out of range (cube edge / 2^20 = {} to 1e8 m)", file.string(),
         spacing, edge / double(1 << 20));
  if (!(precision > 0))
    fail("{}: precision {} is out of range (positive and finite)", file.string(), precision);
}

}  // namespace

void plan_part(Build& b) {
  if (!b.opt.subset_count) return;
  const auto [index, count] =
      parse_subset(fmt::format("{}/{}", b.opt.subset_index, b.opt.subset_count));
  (void)index;
  // Octree nodes where N is a power of 8, else columns of a quadtree level.
  int l8 = 0, l4 = 0;
  for (uint64_t v = 1; v < count; v *= 8) ++l8;
  for (uint64_t v = 1; v < count; v *= 4) ++l4;
  if ((uint64_t(1) << (3 * l8)) == count) {
    b.part_level = l8;
  } else {
    b.part_level = l4;
    b.part_columns = true;
  }
}

void write_part(Build& b) {
  using nlohmann::json;
  const TileOptions& opt = b.opt;
  fs::create_directories(b.dir / "roots");
  json roots = json::array();
  for (auto& [k, f] : b.pending_roots) {
    const uint64_t points = fs::file_size(f) / sizeof(TilePoint);
    fs::rename(f, b.dir / "roots" / (k.name() + ".bin"));
    roots.push_back({k.level, k.x, k.y, k.z, points});
  }
  b.pending_roots.clear();
  json nodes = json::array();
  for (auto& [k, info] : b.nodes) {
    const Box& box = info.content;
    nodes.push_back({k.level, k.x, k.y, k.z, info.points, box.min.x, box.min.y, box.min.z,
                     box.max.x, box.max.y, box.max.z});
  }
  const glm::dvec3& o = b.frame.origin_ecef;
  json part = {{"stipple_part", 1},
               {"subset", {opt.subset_index, opt.subset_count}},
               {"level", b.part_level},
               {"points", b.total_points},
               {"inputs", opt.inputs},
               {"format", opt.format == Format::Glb ? "glb" : "pnts"},
               {"compression", opt.compression},
               {"implicit", opt.implicit},
               {"subtree_levels", opt.subtree_levels},
               {"max_node_points", opt.max_node_points},
               {"cube", {b.cube_min.x, b.cube_min.y, b.cube_min.z, b.cube_size}},
               {"root_spacing", b.root_spacing},
               {"max_level", b.max_level},
               {"precision", b.content.precision},
               {"rgb", b.content.rgb},
               {"gps_time", b.content.gps_time},
               {"frame_origin", {o.x, o.y, o.z}},
               {"nodes", nodes},
               {"roots", roots}};
  const std::string text = part.dump(1);
  write_file(b.dir / "part.json", text.data(), text.size());
}

PartSet read_parts(const MergeOptions& options) {
  if (options.parts.empty()) fail("tile merge: no parts");
  std::vector<nlohmann::json> parts;
  std::vector<fs::path> dirs;
  std::set<uint32_t> seen;
  uint32_t count = 0;
  for (const std::string& dir : options.parts) {
    const fs::path file = fs::path(dir) / "part.json";
    std::ifstream in(file);
    if (!in) fail("{}: not a part of a split tiling (no part.json; made by tile --subset)", dir);
    nlohmann::json p = nlohmann::json::parse(in, nullptr, false);
    if (p.is_discarded() || !p.is_object() || !p.contains("stipple_part") ||
        p["stipple_part"] != 1 || !part_json_shape_ok(p))
      fail("{}: not a part.json written by stipple tile --subset", file.string());
    const uint32_t index = p["subset"][0].get<uint32_t>(), n = p["subset"][1].get<uint32_t>();
    try {
      parse_subset(fmt::format("{}/{}", index, n));  // N a power of 4 or 8, I < N
    } catch (const Error&) {
      fail("{}: part {}/{} is not one of N parts with N a power of 4 or 8", dir, index, n);
    }
    if (count == 0) count = n;
    if (n != count)
      fail("{}: part {}/{} of another split (the first part is of {})", dir, index, n, count);
    if (!seen.insert(index).second) fail("{}: part {}/{} is given twice", dir, index, n);
    check_part_ranges(p, file);
    if (!parts.empty()) {
      for (const char* key : {"cube", "root_spacing", "format", "compression", "implicit",
                              "subtree_levels", "max_node_points", "frame_origin", "precision",
                              "rgb", "gps_time", "level", "max_level"})
        if (p[key] != parts.front()[key])
          fail("{}: its {} differs from {}'s: the parts are of different tilings", dir, key,
               options.parts.front());
      // Inputs by file name: parts tiled on other machines see the same files under other
      // mounts or relative paths; the cube, equal above, ties them to the same data.
      auto names = [](const nlohmann::json& inputs) {
        std::vector<std::string> n;
        for (const auto& in : inputs) n.push_back(fs::path(in.get<std::string>()).filename());
        return n;
      };
      if (names(p["inputs"]) != names(parts.front()["inputs"]))
        fail("{}: its inputs differ from {}'s: the parts are of different tilings", dir,
             options.parts.front());
    }
    parts.push_back(std::move(p));
    dirs.push_back(dir);
  }
  if (seen.size() != count) {
    std::string missing;
    for (uint32_t i = 0; i < count && missing.size() < 200; ++i)
      if (!seen.count(i)) missing += (missing.empty() ? "" : ", ") + fmt::format("{}/{}", i, count);
    fail("tile merge: {} of {} parts given; missing {}", seen.size(), count, missing);
  }
  PartSet set;
  TileOptions& o = set.options;
  o.output = options.output;
  o.force = options.force;
  o.threads = options.threads;
  o.max_memory = options.max_memory;
  o.progress = options.progress;
  const nlohmann::json& f = parts.front();
  o.format = f["format"] == "pnts" ? Format::Pnts : Format::Glb;
  o.compression = f["compression"].get<std::string>();
  o.implicit = f["implicit"].get<bool>();
  o.subtree_levels = f["subtree_levels"].get<int>();
  o.max_node_points = f["max_node_points"].get<size_t>();
  // Every part names the same inputs (checked above): the split tiled them once.
  for (const auto& in : f["inputs"]) o.inputs.push_back(in.get<std::string>());
  set.parts = std::move(parts);
  set.dirs = std::move(dirs);
  return set;
}

void settings_from_part(Build& b, const nlohmann::json& first) {
  auto vec = [](const nlohmann::json& a) {
    return glm::dvec3(a[0].get<double>(), a[1].get<double>(), a[2].get<double>());
  };
  b.cube_min = vec(first["cube"]);
  b.cube_size = first["cube"][3].get<double>();
  b.root_spacing = first["root_spacing"].get<double>();
  b.max_level = first["max_level"].get<int>();
  b.content.precision = first["precision"].get<double>();
  b.content.rgb = first["rgb"].get<bool>();
  b.content.gps_time = first["gps_time"].get<bool>();
  b.content.compression = b.opt.compression == "meshopt" ? Compression::Meshopt
                          : b.opt.compression == "draco" ? Compression::Draco
                                                         : Compression::None;
  b.frame = make_local_frame(vec(first["frame_origin"]));
}

void link_parts(Build& b, const std::vector<nlohmann::json>& parts,
                const std::vector<fs::path>& dirs) {
  uint64_t tiles = 0;
  // The parts' level; the merge itself builds down to the root (b.part_level stays 0).
  const int part_level = parts.front()["level"].get<int>();
  if (part_level < 1 || part_level > 15 || b.max_level < part_level || b.max_level > 30)
    fail("{}: part level {} or maximum level {} is out of range", dirs[0].string(), part_level,
         b.max_level);
  // A key from a part.json: a node of the cube, below (or, for a root, at) the part level.
  auto key_of = [&](const nlohmann::json& a, bool root, const fs::path& dir) {
    const NodeKey k{a[0].get<int>(), a[1].get<uint32_t>(), a[2].get<uint32_t>(),
                    a[3].get<uint32_t>()};
    const bool level_ok = root ? k.level == part_level : k.level > part_level && k.level <= 30;
    const uint64_t n = level_ok ? uint64_t(1) << k.level : 0;
    if (!level_ok || k.x >= n || k.y >= n || k.z >= n)
      fail("{}: part.json names tile {}, outside the part's levels", dir.string(), k.name());
    return k;
  };
  for (size_t i = 0; i < parts.size(); ++i) {
    const nlohmann::json& p = parts[i];
    b.total_points += p["points"].get<uint64_t>();
    for (const auto& n : p["nodes"]) {
      const NodeKey k = key_of(n, false, dirs[i]);
      NodeInfo info;
      info.points = n[4].get<uint64_t>();
      if (info.points > 0) {
        info.content.min = glm::dvec3(n[5].get<double>(), n[6].get<double>(), n[7].get<double>());
        info.content.max = glm::dvec3(n[8].get<double>(), n[9].get<double>(), n[10].get<double>());
      }
      if (b.nodes.count(k)) fail("{}: tile {} is in another part too", dirs[i].string(), k.name());
      b.nodes[k] = info;
      b.written += info.points;
    }
    if (fs::is_directory(dirs[i] / "tiles"))
      for (const auto& e : fs::directory_iterator(dirs[i] / "tiles")) {
        link_or_copy(e.path(), b.dir / "tiles" / e.path().filename(), dirs[i]);
        ++tiles;
      }
    for (const auto& r : p["roots"]) {
      const NodeKey k = key_of(r, true, dirs[i]);
      if (b.pending_roots.count(k))
        fail("{}: root {} is in another part too", dirs[i].string(), k.name());
      const fs::path from = dirs[i] / "roots" / (k.name() + ".bin");
      if (!fs::exists(from) || fs::file_size(from) != r[4].get<uint64_t>() * sizeof(TilePoint))
        fail("{}: {} is missing or not of {} points", dirs[i].string(), from.string(),
             r[4].get<uint64_t>());
      const fs::path to = b.tmp / ("root-" + k.name() + ".bin");
      fs::copy_file(from, to);  // build_upper_levels consumes it
      b.pending_roots[k] = to;
    }
    report(b, "merging", i + 1, parts.size());
  }
  STIPPLE_INFO("tile merge: {} parts, {} points, {} tiles linked", parts.size(), b.total_points,
               tiles);
}

void check_merged(const Build& b) {
  if (b.written != b.total_points)
    fail("tile merge: the parts' tiles and roots hold {} points, their part.json files say {}",
         b.written.load(), b.total_points);
  if (b.total_points == 0 || !b.nodes.count(NodeKey{}))
    fail("tile merge: the parts hold no points");
  for (const auto& [k, info] : b.nodes)
    if (k.level > 0 && !b.nodes.count(k.parent()))
      fail("tile merge: tile {} has no parent in any part", k.name());
}

}  // namespace stipple::tiler::detail
