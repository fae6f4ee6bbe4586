// The web build has no LASzip (it is not built for WebAssembly yet): LAZ and COPC inputs are
// an error naming the file; LAS files and 3D Tiles are read.
#include "las_detail.hpp"
#include "stipple/core/error.hpp"

namespace stipple::io::detail {

std::unique_ptr<LazDecoder> open_laz_decoder(const std::string& name, const std::filesystem::path*,
                                             std::span<const uint8_t>, const RecordLayout&) {
  fail(
      "{}: LAZ is not decoded by the web build (no LASzip for WebAssembly yet): open a LAS "
      "file or a tileset",
      name);
}

std::unique_ptr<LazEncoder> open_laz_encoder(const std::filesystem::path& path, const LasHeader&,
                                             const std::vector<Vlr>&, const RecordLayout&) {
  fail("{}: the web build writes no LAZ files", path.string());
}

}  // namespace stipple::io::detail
