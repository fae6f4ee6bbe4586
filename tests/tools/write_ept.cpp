// Writes an Entwine Point Tile cloud with the tests' writer (tests/common/ept_writer.hpp), for the
// web viewer's zstandard nodes (web/compressed.test.mjs):
//   stipple_write_ept DIR POINTS [laszip|binary|zstandard [NODE_CAP STEP]]
#include <cstdio>
#include <string>

#include "ept_writer.hpp"

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: %s DIR POINTS [laszip|binary|zstandard [NODE_CAP STEP]]\n",
                 argv[0]);
    return 2;
  }
  const std::string type = argc > 3 ? argv[3] : "zstandard";
  const size_t cap = argc > 4 ? std::stoul(argv[4]) : 400;
  const int step = argc > 5 ? std::stoi(argv[5]) : 2;
  auto r = stipple::test::write_ept(argv[1], stipple::test::ept_points(std::stoul(argv[2])), type,
                                    cap, step);
  std::printf("{\"nodes\": %zu, \"hierarchy_files\": %zu, \"depth\": %d}\n", r.nodes,
              r.hierarchy_files, r.depth);
  return 0;
}
