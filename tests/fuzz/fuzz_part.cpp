// Fuzzes `stipple tile merge` (tiler::merge_parts) through to the merge itself: the input is one
// or more part.json texts separated by NUL bytes. The first is the template part; the harness
// makes the N part directories its "subset" names (N of 4 or 8): the template's own index gets
// the template, each other index the next text of the input, or, where the input has no more,
// the template with that index and no nodes, roots or points. Each part directory gets the root
// files its part.json lists (that many points inside the root's node of the part's cube) and a
// small content file per node, so that a well-formed input runs the whole merge: part checks,
// tile links, the upper levels built from the roots, tileset.json. Every malformed input must
// end in stipple::Error.
#include <unistd.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>
#include <vector>

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <glm/glm.hpp>
#include <nlohmann/json.hpp>

#include "stipple/core/error.hpp"
#include "stipple/tiler/tile_point.hpp"
#include "stipple/tiler/tiler.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

void write(const fs::path& file, std::string_view text) {
  std::ofstream out(file, std::ios::binary | std::ios::trunc);
  out.write(text.data(), std::streamsize(text.size()));
}

bool uint_at(const json& a, size_t i, uint64_t limit) {
  return a.is_array() && a.size() > i && a[i].is_number_unsigned() && a[i].get<uint64_t>() <= limit;
}

// Root files (as write_part leaves them: LEVEL-X-Y-Z.bin of TilePoints) and content files for
// what `part` lists, within bounds that keep one run short; entries out of them get no file
// (the merge must then refuse the part).
void populate(const fs::path& dir, const json& part, uint32_t seed) {
  fs::create_directories(dir / "roots");
  fs::create_directories(dir / "tiles");
  if (!part.is_object()) return;
  glm::dvec3 cube_min(0.0);
  double edge = 100.0;
  if (part.contains("cube") && part["cube"].is_array() && part["cube"].size() == 4) {
    const json& c = part["cube"];
    bool ok = true;
    for (size_t i = 0; i < 4; ++i) ok = ok && c[i].is_number() && std::isfinite(c[i].get<double>());
    if (ok) {
      cube_min = glm::dvec3(c[0].get<double>(), c[1].get<double>(), c[2].get<double>());
      edge = c[3].get<double>();
    }
  }
  const std::string ext = part.value("format", json("glb")) == json("pnts") ? "pnts" : "glb";
  uint64_t budget = 20000;  // points over all roots of the part
  if (part.contains("roots") && part["roots"].is_array()) {
    for (const json& r : part["roots"]) {
      if (!uint_at(r, 0, 30) || !uint_at(r, 1, ~0u) || !uint_at(r, 2, ~0u) || !uint_at(r, 3, ~0u) ||
          !uint_at(r, 4, budget))
        continue;
      const uint64_t level = r[0].get<uint64_t>(), n = r[4].get<uint64_t>();
      budget -= n;
      const double node = edge / double(uint64_t(1) << level);
      const glm::dvec3 lo =
          cube_min + glm::dvec3(double(r[1].get<uint64_t>()), double(r[2].get<uint64_t>()),
                                double(r[3].get<uint64_t>())) *
                         node;
      std::vector<stipple::tiler::TilePoint> points(n);
      uint32_t s = seed * 2654435761u + uint32_t(n);
      auto next = [&s] {
        s = s * 1664525u + 1013904223u;
        return double(s >> 8) / double(1u << 24);
      };
      for (auto& p : points) {
        p = {};
        p.x = lo.x + node * next(), p.y = lo.y + node * next(), p.z = lo.z + node * next();
        p.gps_time = next() * 1e6;
        p.intensity = uint16_t(s);
        p.r = uint8_t(s >> 3), p.g = uint8_t(s >> 11), p.b = uint8_t(s >> 19);
        p.classification = uint8_t(s % 20);
        p.return_number = 1;
      }
      const std::string name = fmt::format("{}-{}-{}-{}.bin", level, r[1].get<uint64_t>(),
                                           r[2].get<uint64_t>(), r[3].get<uint64_t>());
      write(dir / "roots" / name, std::string_view(reinterpret_cast<const char*>(points.data()),
                                                   points.size() * sizeof(points[0])));
    }
  }
  if (part.contains("nodes") && part["nodes"].is_array()) {
    size_t files = 0;
    for (const json& n : part["nodes"]) {
      if (files++ >= 256) break;
      if (!uint_at(n, 0, 30) || !uint_at(n, 1, ~0u) || !uint_at(n, 2, ~0u) || !uint_at(n, 3, ~0u))
        continue;
      const std::string name =
          fmt::format("{}-{}-{}-{}.{}", n[0].get<uint64_t>(), n[1].get<uint64_t>(),
                      n[2].get<uint64_t>(), n[3].get<uint64_t>(), ext);
      write(dir / "tiles" / name, name);
    }
  }
}

}  // namespace

// The merge logs its phases at info level: a few formatted lines per execution, written to the
// fuzzer's log, that slowed every execution and said nothing.
extern "C" int LLVMFuzzerInitialize(int*, char***) {
  spdlog::set_level(spdlog::level::off);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const fs::path dir = [] {
    // In memory where the machine has /dev/shm: the part directories are made and removed for
    // every input, and on a disk file system (ext4) that took most of the time of a run.
    const fs::path base =
        fs::is_directory("/dev/shm") ? fs::path("/dev/shm") : fs::temp_directory_path();
    fs::path d = base / ("stipple-fuzz-part-" + std::to_string(::getpid()));
    fs::create_directories(d);
    return d;
  }();
  std::vector<std::string_view> texts;
  const std::string_view input(reinterpret_cast<const char*>(data), size);
  for (size_t at = 0;;) {
    const size_t end = input.find('\0', at);
    texts.push_back(input.substr(at, end == std::string_view::npos ? end : end - at));
    if (end == std::string_view::npos || texts.size() == 8) break;
    at = end + 1;
  }
  for (const auto& e : fs::directory_iterator(dir)) fs::remove_all(e.path());

  stipple::tiler::MergeOptions options;
  options.output = (dir / "out").string();
  options.force = true;
  options.threads = 1;
  // The part directories: N from the template's "subset" when it is one of 4 or 8 parts, else
  // the template alone (the merge refuses it, or finds parts missing).
  const json tmpl = json::parse(texts[0], nullptr, false);
  uint64_t index = 0, count = 1;
  if (tmpl.is_object() && tmpl.contains("subset") && uint_at(tmpl["subset"], 0, 7) &&
      uint_at(tmpl["subset"], 1, 8)) {
    index = tmpl["subset"][0].get<uint64_t>(), count = tmpl["subset"][1].get<uint64_t>();
    if ((count != 4 && count != 8) || index >= count) index = 0, count = 1;
  }
  size_t next_text = 1;
  for (uint64_t i = 0; i < count; ++i) {
    const fs::path part = dir / fmt::format("part{}", i);
    fs::create_directories(part);
    std::string text;
    json parsed;
    if (i == index) {
      text = std::string(texts[0]);
      parsed = tmpl;
    } else if (next_text < texts.size()) {
      text = std::string(texts[next_text++]);
      parsed = json::parse(text, nullptr, false);
    } else {
      parsed = tmpl;
      parsed["subset"] = {i, count};
      parsed["nodes"] = json::array();
      parsed["roots"] = json::array();
      parsed["points"] = 0;
      text = parsed.dump();
    }
    write(part / "part.json", text);
    populate(part, parsed, uint32_t(i + 1));
    options.parts.push_back(part.string());
  }
  try {
    stipple::tiler::merge_parts(options);
  } catch (const stipple::Error&) {
  }
  return 0;
}
