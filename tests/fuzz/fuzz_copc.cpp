// libFuzzer target: arbitrary bytes as a COPC hierarchy page, through the entry parser and the
// page reader that turns entries into tiles (keys, parents, child pages, cycles, sizes), then
// every child page it finds is read again from the same bytes (a page pointing at itself or at
// garbage), a few levels deep. Any error must come back as an error of the expansion.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include <spdlog/spdlog.h>

#include "stipple/core/error.hpp"
#include "stipple/io/copc.hpp"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  spdlog::set_level(spdlog::level::off);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace stipple::io;
  std::vector<uint8_t> bytes(data, data + size);
  try {
    (void)parse_copc_page(bytes, "fuzz page", 1ull << 30);
  } catch (const stipple::Error&) {
  }
  auto file = std::make_shared<CopcFile>();
  file->uri = "fuzz.copc.laz";
  file->file_size = 1ull << 30;
  file->info.halfsize = 100;
  file->info.spacing = 1;
  Fetcher fetcher = [&](const std::string&) { return bytes; };
  TilesetOptions options;
  options.max_tiles = 100'000;
  PendingChildren pending;
  pending.kind = PendingChildren::Kind::CopcPage;
  pending.uris = {range_uri(file->uri, 375, size ? size : 1)};
  pending.copc = file;
  std::vector<PendingChildren> todo{pending};
  for (int round = 0; round < 4 && !todo.empty(); ++round) {
    std::vector<PendingChildren> next;
    for (const auto& p : todo) {
      Expansion e = read_copc_page(0, p, 1, fetcher, options);
      for (const auto& t : e.tiles) {
        if (t.parent >= int32_t(e.tiles.size())) __builtin_trap();
        if (t.pending && next.size() < 8) next.push_back(*t.pending);
      }
    }
    todo = std::move(next);
  }
  return 0;
}
