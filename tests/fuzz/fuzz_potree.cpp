// libFuzzer target: arbitrary bytes as Potree 2.0 metadata.json (input starting with '{'), else
// as a hierarchy.bin chunk read into tiles (record types, child masks, proxies, sizes) with every
// proxy's chunk read again from the same bytes a few levels deep, and as a node of octree.bin.
// Any error must come back as stipple::Error or as an error of the expansion.
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

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace stipple::io;
  std::vector<uint8_t> bytes(data, data + size);
  if (size > 0 && data[0] == '{') {
    try {
      (void)parse_potree_metadata(bytes, "fuzz/metadata.json");
    } catch (const stipple::Error&) {
    }
    return 0;
  }
  auto cloud = fixed_cloud();
  Fetcher fetcher = [&](const std::string&) { return bytes; };
  TilesetOptions options;
  options.max_tiles = 100'000;
  PendingChildren pending;
  pending.kind = PendingChildren::Kind::PotreeChunk;
  pending.uris = {range_uri(cloud->hierarchy_uri, 0, size ? size : 1)};
  pending.potree = cloud;
  std::vector<PendingChildren> todo{pending};
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
  const size_t points = cloud->record_size ? size / cloud->record_size : 0;
  DecodeLimits limits;
  limits.max_points = 100'000;
  try {
    (void)decode_potree_node(
        *cloud, bytes,
        range_uri(cloud->octree_uri, 0, size ? size : 1) + "&points=" + std::to_string(points),
        limits);
  } catch (const stipple::Error&) {
  }
  return 0;
}
