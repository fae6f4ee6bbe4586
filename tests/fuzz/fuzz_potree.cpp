// libFuzzer target: arbitrary bytes as Potree 2.0 metadata.json and Potree 1.x cloud.js (input
// starting with '{'; a 1.0-1.4 cloud.js's hierarchy list made into tiles), else as a hierarchy.bin
// chunk (record types, child masks, proxies, sizes) and as a 1.x .hrc file, each read into tiles
// with every pending chunk or file read again from the same bytes a few levels deep, and as a node:
// of octree.bin in DEFAULT and BROTLI encoding, and a 1.x binary node (uint32 positions, and 1.3's
// float32 ones). Any error must come back as stipple::Error or as an error of the expansion.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include <spdlog/spdlog.h>

#include "stipple/core/error.hpp"
#include "stipple/io/fetch.hpp"
#include "stipple/io/potree.hpp"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  spdlog::set_level(spdlog::level::off);
  return 0;
}

namespace {

// A valid cloud whose records are position, rgb, intensity, gps-time and an int64 extra.
std::shared_ptr<const stipple::io::PotreeCloud> fixed_cloud() {
  static const std::string meta = R"({"version":"2.0","points":1000,"scale":[0.001,0.001,0.001],
    "offset":[0,0,0],"spacing":1,"boundingBox":{"min":[0,0,0],"max":[100,100,100]},
    "hierarchy":{"firstChunkSize":22,"stepSize":2,"depth":8},"encoding":"DEFAULT",
    "attributes":[{"name":"position","size":12,"numElements":3,"elementSize":4,"type":"int32"},
    {"name":"rgb","size":6,"numElements":3,"elementSize":2,"type":"uint16"},
    {"name":"intensity","size":2,"numElements":1,"elementSize":2,"type":"uint16"},
    {"name":"gps-time","size":8,"numElements":1,"elementSize":8,"type":"double"},
    {"name":"extra","size":8,"numElements":1,"elementSize":8,"type":"int64"}]})";
  static const auto cloud = stipple::io::parse_potree_metadata(
      std::span(reinterpret_cast<const uint8_t*>(meta.data()), meta.size()), "fuzz/metadata.json");
  return cloud;
}

// The same cloud with BROTLI nodes.
std::shared_ptr<const stipple::io::PotreeCloud> brotli_cloud() {
  static const auto cloud = [] {
    auto c = std::make_shared<stipple::io::PotreeCloud>(*fixed_cloud());
    c->encoding = "BROTLI";
    return c;
  }();
  return cloud;
}

// A Potree 1.8 cloud of binary nodes: position, colour, intensity, oct16 and float normals, GPS
// time, an extra of a type Potree 1 cannot name.
std::shared_ptr<const stipple::io::PotreeCloud> cloud1() {
  static const std::string js = R"({"version":"1.8","octreeDir":"data","points":1000,
    "boundingBox":{"lx":0,"ly":0,"lz":0,"ux":100,"uy":100,"uz":100},"scale":0.001,
    "spacing":1,"hierarchyStepSize":3,"pointAttributes":[
    {"name":"POSITION_CARTESIAN","size":12,"elements":3,"elementSize":4,"type":"int32"},
    {"name":"RGBA","size":4,"elements":4,"elementSize":1,"type":"uint8"},
    {"name":"intensity","size":2,"elements":1,"elementSize":2,"type":"uint16"},
    {"name":"NORMAL_OCT16","size":2,"elements":2,"elementSize":1,"type":"int8"},
    {"name":"NORMAL","size":12,"elements":3,"elementSize":4,"type":"float"},
    {"name":"gps-time","size":8,"elements":1,"elementSize":8,"type":"double"},
    {"name":"blob","size":3,"elements":1,"elementSize":3,"type":"undefined"}]})";
  static const auto cloud = stipple::io::parse_potree1_cloud(
      std::span(reinterpret_cast<const uint8_t*>(js.data()), js.size()), "fuzz/cloud.js");
  return cloud;
}

// A Potree 1.3 cloud: float positions in the cloud's coordinates, its octree listed in cloud.js.
std::shared_ptr<const stipple::io::PotreeCloud> cloud13() {
  static const std::string js = R"({"version":"1.3","octreeDir":"data",
    "boundingBox":{"lx":0,"ly":0,"lz":0,"ux":100,"uy":100,"uz":100},"spacing":1,
    "pointAttributes":["POSITION_CARTESIAN","COLOR_PACKED","INTENSITY"],
    "hierarchy":[["r",10],["r0",5]]})";
  static const auto cloud = stipple::io::parse_potree1_cloud(
      std::span(reinterpret_cast<const uint8_t*>(js.data()), js.size()), "fuzz/cloud.js");
  return cloud;
}

// Reads `first` and what it leaves pending, a few levels deep, everything from the same bytes.
void expand(const stipple::io::PendingChildren& first, const stipple::io::Fetcher& fetcher) {
  using namespace stipple::io;
  TilesetOptions options;
  options.max_tiles = 100'000;
  std::vector<PendingChildren> todo{first};
  for (int round = 0; round < 4 && !todo.empty(); ++round) {
    std::vector<PendingChildren> next;
    for (const auto& p : todo) {
      Expansion e = read_potree_chunk(0, p, 1, fetcher, options);
      for (const auto& t : e.tiles) {
        if (t.parent >= int32_t(e.tiles.size())) __builtin_trap();
        if (t.pending && next.size() < 8) next.push_back(*t.pending);
      }
    }
    todo = std::move(next);
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace stipple::io;
  std::vector<uint8_t> bytes(data, data + size);
  if (size > 0 && data[0] == '{') {
    try {
      (void)parse_potree_metadata(bytes, "fuzz/metadata.json");
    } catch (const stipple::Error&) {
    }
    try {
      // The whole tileset: 1.0-1.4 make their tiles from the list (a 1.5-1.8 root .hrc is these
      // bytes again, and fails).
      TilesetOptions options;
      options.max_tiles = 100'000;
      const Tileset ts = load_potree_tileset(
          "fuzz/cloud.js", [&](const std::string&) { return bytes; }, options);
      for (size_t i = 0; i < ts.tiles.size(); ++i)
        if (ts.tiles[i].parent >= int32_t(i)) __builtin_trap();  // parents before children
    } catch (const stipple::Error&) {
    }
    return 0;
  }
  Fetcher fetcher = [&](const std::string&) { return bytes; };
  auto cloud = fixed_cloud();
  PendingChildren pending;
  pending.kind = PendingChildren::Kind::PotreeChunk;
  pending.uris = {range_uri(cloud->hierarchy_uri, 0, size ? size : 1)};
  pending.potree = cloud;
  expand(pending, fetcher);
  pending.uris = {"fuzz/data/r/r.hrc"};
  pending.potree = cloud1();
  expand(pending, fetcher);
  DecodeLimits limits;
  limits.max_points = 100'000;
  auto decode = [&](const PotreeCloud& c, const std::string& uri) {
    try {
      (void)decode_potree_node(c, bytes, uri, limits);
    } catch (const stipple::Error&) {
    }
  };
  const size_t points = cloud->record_size ? size / cloud->record_size : 0;
  const std::string node = range_uri(cloud->octree_uri, 0, size ? size : 1) + "&points=";
  decode(*cloud, node + std::to_string(points));
  // A BROTLI node's count says nothing of its compressed size: a few counts.
  for (size_t n : {size_t(1), size_t(7), points, size * 4})
    decode(*brotli_cloud(), node + std::to_string(n));
  const size_t points1 = size / cloud1()->record_size;
  decode(*cloud1(), "fuzz/data/r/r01.bin#points=" + std::to_string(points1) + "&key=r01");
  const size_t points13 = size / cloud13()->record_size;
  decode(*cloud13(), "fuzz/data/r0#points=" + std::to_string(points13) + "&key=r0");
  return 0;
}
