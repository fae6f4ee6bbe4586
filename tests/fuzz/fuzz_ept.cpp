// libFuzzer target: arbitrary bytes as Entwine Point Tile input. The first byte picks what they
// are: 'M' ept.json, 'H' a hierarchy file read into tiles (keys, counts, -1 subtrees read again
// from the same bytes a few levels deep), 'B' a binary node, 'Z' a zstandard node, anything else
// a laszip node. Any error must come back as stipple::Error or as an error of the expansion.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include <spdlog/spdlog.h>

#include "stipple/core/error.hpp"
#include "stipple/io/ept.hpp"
#include "stipple/io/fetch.hpp"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  spdlog::set_level(spdlog::level::off);
  return 0;
}

namespace {

std::shared_ptr<const stipple::io::EptCloud> fixed_cloud(const char* type) {
  const std::string meta = std::string(R"({"version":"1.0.0","dataType":")") + type +
                           R"(","hierarchyType":"json","points":1000,"span":128,
    "bounds":[0,0,0,100,100,100],"schema":[
    {"name":"X","type":"signed","size":4,"scale":0.01,"offset":0},
    {"name":"Y","type":"signed","size":4,"scale":0.01,"offset":0},
    {"name":"Z","type":"signed","size":4,"scale":0.01,"offset":0},
    {"name":"Intensity","type":"unsigned","size":2},{"name":"GpsTime","type":"float","size":8},
    {"name":"Red","type":"unsigned","size":2},{"name":"Green","type":"unsigned","size":2},
    {"name":"Blue","type":"unsigned","size":2},{"name":"Big","type":"signed","size":8}]})";
  return stipple::io::parse_ept_metadata(
      std::span(reinterpret_cast<const uint8_t*>(meta.data()), meta.size()), "fuzz/ept.json");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace stipple::io;
  if (size == 0) return 0;
  const char kind = char(data[0]);
  std::vector<uint8_t> bytes(data + 1, data + size);
  DecodeLimits limits;
  limits.max_points = 100'000;
  try {
    if (kind == 'M') {
      (void)parse_ept_metadata(bytes, "fuzz/ept.json");
    } else if (kind == 'H') {
      static const auto cloud = fixed_cloud("binary");
      Fetcher fetcher = [&](const std::string&) { return bytes; };
      TilesetOptions options;
      options.max_tiles = 100'000;
      PendingChildren pending;
      pending.kind = PendingChildren::Kind::EptHierarchy;
      pending.uris = {"fuzz/ept-hierarchy/0-0-0-0.json"};
      pending.ept = cloud;
      std::vector<PendingChildren> todo{pending};
      for (int round = 0; round < 4 && !todo.empty(); ++round) {
        std::vector<PendingChildren> next;
        for (const auto& p : todo) {
          Expansion e = read_ept_hierarchy(0, p, 1, fetcher, options);
          for (const auto& t : e.tiles) {
            if (t.parent >= int32_t(e.tiles.size())) __builtin_trap();
            if (t.pending && next.size() < 8) next.push_back(*t.pending);
          }
        }
        todo = std::move(next);
      }
    } else {
      static const auto binary = fixed_cloud("binary"), zstd = fixed_cloud("zstandard"),
                        laz = fixed_cloud("laszip");
      const auto& cloud = kind == 'B' ? binary : kind == 'Z' ? zstd : laz;
      const size_t points = kind == 'B' ? bytes.size() / cloud->record_size : bytes.size() / 8;
      (void)decode_ept_node(*cloud, bytes,
                            "fuzz/ept-data/0-0-0-0.bin#points=" + std::to_string(points), limits);
    }
  } catch (const stipple::Error&) {
  }
  return 0;
}
