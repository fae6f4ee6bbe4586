// libFuzzer target: arbitrary bytes through the JSON readers of user files: GeoJSON (clip
// polygons, saved measurements, as the viewer loads them) and viewer input scripts. Any
// stipple::Error is a correct rejection; crashes, sanitizer reports, hangs and huge allocations
// are bugs.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include <spdlog/spdlog.h>

#include "stipple/core/error.hpp"
#include "stipple/io/geojson.hpp"
#include "stipple/tools/measure.hpp"
#include "stipple/viewer/script.hpp"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  spdlog::set_level(spdlog::level::off);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  try {
    const stipple::io::GeoDocument doc = stipple::io::parse_geojson(text, "fuzz.geojson");
    (void)stipple::io::geojson_text(doc.features, 2992);
    stipple::tools::SourceFrame frame;
    for (size_t i = 0; i < doc.features.size(); ++i) {
      try {
        (void)stipple::tools::from_feature(doc.features[i], frame, i, "fuzz.geojson");
      } catch (const stipple::Error&) {
      }
    }
    (void)stipple::io::geojson_polygons(doc, "fuzz.geojson");
  } catch (const stipple::Error&) {
  }
  try {
    (void)stipple::viewer::parse_input_script(text, "fuzz.json");
  } catch (const stipple::Error&) {
  }
  return 0;
}
