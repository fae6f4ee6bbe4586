#include "stipple/io/content_summary.hpp"

#include <algorithm>
#include <cstring>
#include <mutex>

#include <nlohmann/json.hpp>

#include "stipple/core/error.hpp"
#include "stipple/core/progress.hpp"
#include "stipple/core/thread_pool.hpp"
#include "stipple/io/copc.hpp"
#include "stipple/io/fetch.hpp"

namespace stipple::io {
namespace {

using json = nlohmann::json;

uint32_t u32(const std::vector<uint8_t>& b, size_t at) {
  if (b.size() < at + 4) fail("the header is cut short");
  uint32_t v;
  std::memcpy(&v, b.data() + at, 4);
  return v;
}

// The first `size` bytes (or all of a shorter file): a range read, or the whole resource where a
// range cannot be had.
std::vector<uint8_t> head(const std::string& uri, uint64_t size, const Fetcher& fetcher) {
  try {
    return fetcher(range_uri(uri, 0, size));
  } catch (const Error&) {
    std::vector<uint8_t> all = fetcher(uri);  // a short file, or a server without ranges
    if (all.size() > size) all.resize(size);
    return all;
  }
}

// Points of a glTF document: POSITION counts of the point primitives of the meshes its nodes
// use (each use counts), or of every mesh when it has no nodes.
void summarize_gltf(const json& g, ContentSummary& s) {
  if (!g.is_object()) fail("the glTF JSON is not an object");
  const json accessors = g.value("accessors", json::array());
  const json meshes = g.value("meshes", json::array());
  const json nodes = g.value("nodes", json::array());
  if (!accessors.is_array() || !meshes.is_array() || !nodes.is_array())
    fail("accessors, meshes or nodes is not an array");
  std::vector<uint64_t> uses(meshes.size(), 0);
  bool any_node = false;
  for (const auto& n : nodes)
    if (n.is_object() && n.contains("mesh") && n["mesh"].is_number_unsigned() &&
        n["mesh"].get<uint64_t>() < meshes.size()) {
      ++uses[n["mesh"].get<size_t>()];
      any_node = true;
    }
  if (!any_node) std::fill(uses.begin(), uses.end(), 1);
  for (size_t m = 0; m < meshes.size(); ++m) {
    if (!meshes[m].is_object()) continue;
    for (const auto& p : meshes[m].value("primitives", json::array())) {
      if (!p.is_object()) continue;
      if (p.value("mode", 4) != 0) {
        s.other_primitives += uses[m];
        continue;
      }
      const json attrs = p.value("attributes", json::object());
      if (!attrs.is_object() || !attrs.contains("POSITION") ||
          !attrs["POSITION"].is_number_unsigned() ||
          attrs["POSITION"].get<uint64_t>() >= accessors.size())
        fail("a point primitive has no valid POSITION");
      const json& a = accessors[attrs["POSITION"].get<size_t>()];
      const uint64_t count = a.is_object() ? a.value("count", uint64_t(0)) : 0;
      s.points += count * uses[m];
    }
  }
  s.drawable = s.points > 0;
}

}  // namespace

std::string describe_content_type(const std::string& type) {
  if (type == "b3dm") return "b3dm (batched 3D models)";
  if (type == "i3dm") return "i3dm (instanced 3D models)";
  if (type == "cmpt") return "cmpt (composite tiles)";
  if (type == "glb" || type == "gltf") return type + " meshes";
  if (type == "geojson" || type == "vctr" || type == "geom") return type + " (vector data)";
  return type;
}

ContentSummary summarize_content(const std::string& uri, const Fetcher& fetcher,
                                 uint64_t max_json_bytes) {
  ContentSummary s;
  s.type = "unknown";
  try {
    if (!fragment_field(uri, "points").empty()) {  // an octree node: its count is in its URI
      const std::string path = uri_path(uri);
      // Potree nodes are named r0123...; EPT and COPC nodes D-X-Y-Z.
      s.type = fragment_field(uri, "key").rfind('r', 0) == 0 ? "potree"
               : path.find("/ept-data/") != std::string::npos || path.rfind("ept-data/", 0) == 0
                   ? "ept"
                   : "copc";
      s.points = std::stoull(fragment_field(uri, "points"));
      s.drawable = true;
      return s;
    }
    if (is_tileset_uri(uri)) {
      s.type = "json";
      return s;
    }
    const std::string path = uri_path(uri);
    if (path.ends_with(".gltf")) {
      s.type = "gltf";
      std::vector<uint8_t> bytes = fetcher(uri);
      json g = json::parse(bytes.begin(), bytes.end(), nullptr, false);
      if (g.is_discarded()) fail("not valid JSON");
      summarize_gltf(g, s);
      return s;
    }
    if (path.ends_with(".geojson")) {
      s.type = "geojson";
      return s;
    }
    std::vector<uint8_t> h = head(uri, 28, fetcher);
    if (h.size() < 4) fail("{} bytes are not a tile", h.size());
    const std::string magic(h.begin(), h.begin() + 4);
    if (magic == "pnts") {
      s.type = "pnts";
      const uint32_t ft = u32(h, 12);
      if (ft > max_json_bytes) fail("a feature table JSON of {} bytes", ft);
      std::vector<uint8_t> bytes = head(uri, 28 + uint64_t(ft), fetcher);
      if (bytes.size() < 28 + uint64_t(ft)) fail("the feature table is cut short");
      json j = json::parse(bytes.begin() + 28, bytes.end(), nullptr, false);
      if (!j.is_object() || !j.contains("POINTS_LENGTH") ||
          !j["POINTS_LENGTH"].is_number_unsigned())
        fail("the feature table has no POINTS_LENGTH");
      s.points = j["POINTS_LENGTH"].get<uint64_t>();
      s.drawable = true;
    } else if (magic == "glTF") {
      s.type = "glb";
      const uint32_t length = u32(h, 12);
      if (u32(h, 16) != 0x4E4F534A) fail("the first GLB chunk is not JSON");
      if (length > max_json_bytes) fail("a GLB JSON chunk of {} bytes", length);
      std::vector<uint8_t> bytes = head(uri, 20 + uint64_t(length), fetcher);
      if (bytes.size() < 20 + uint64_t(length)) fail("the GLB JSON chunk is cut short");
      json g = json::parse(bytes.begin() + 20, bytes.end(), nullptr, false);
      if (g.is_discarded()) fail("the GLB JSON chunk is not valid JSON");
      summarize_gltf(g, s);
    } else if (magic == "b3dm" || magic == "i3dm" || magic == "cmpt" || magic == "vctr" ||
               magic == "geom") {
      s.type = magic;
    } else if (magic[0] == '{') {
      s.type = "json";
    } else {
      fail("unknown content magic");
    }
  } catch (const std::exception& e) {
    s.error = fmt::format("{}: {}", uri, e.what());
    s.drawable = false;
  }
  return s;
}

ContentTotals summarize_contents(const std::vector<std::string>& uris, const Fetcher& fetcher,
                                 unsigned threads) {
  std::vector<ContentSummary> all(uris.size());
  {
    Progress progress("reading tile headers", uris.size(), "tiles");
    std::mutex mutex;
    ThreadPool pool(std::max(1u, std::min<unsigned>(threads, unsigned(uris.size()))));
    pool.parallel_for(uris.size(), 16, [&](size_t b, size_t e) {
      for (size_t i = b; i < e; ++i) all[i] = summarize_content(uris[i], fetcher);
      std::lock_guard lock(mutex);
      progress.advance(e - b);
    });
    progress.finish();
  }
  ContentTotals t;
  for (const ContentSummary& s : all) {
    ++t.contents;
    ++t.by_type[s.type];
    t.other_primitives += s.other_primitives;
    if (!s.error.empty()) {
      t.errors.push_back(s.error);
      continue;
    }
    if (s.drawable)
      t.points += s.points;
    else if (s.type != "json")
      ++t.not_drawn[s.type];
  }
  return t;
}

}  // namespace stipple::io
