// Writes a Potree 2.0 cloud with the tests' writer (tests/common/potree_writer.hpp), for the
// potree-core test that proves that writer against Potree's own reader, and for the web viewer's
// BROTLI nodes (web/compressed.test.mjs):
//   stipple_write_potree DIR POINTS [NODE_CAP STEP [no-int64|int64 [brotli]]]
#include <cstdio>
#include <stdexcept>
#include <string>

#include "potree_brotli.hpp"
#include "potree_writer.hpp"

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: %s DIR POINTS [NODE_CAP STEP [no-int64|int64 [brotli]]]\n",
                 argv[0]);
    return 2;
  }
  const size_t cap = argc > 3 ? std::stoul(argv[3]) : 500;
  const int step = argc > 4 ? std::stoi(argv[4]) : 2;
  const bool compress = argc > 6 && std::string(argv[6]) == "brotli";
  auto r = stipple::test::write_potree(argv[1], stipple::test::potree_points(std::stoul(argv[2])),
                                       cap, step, !(argc > 5 && std::string(argv[5]) == "no-int64"),
                                       compress ? stipple::test::potree_brotli : nullptr);
  std::printf("{\"nodes\": %zu, \"chunks\": %zu, \"depth\": %d}\n", r.nodes, r.chunks, r.depth);
  return 0;
}
