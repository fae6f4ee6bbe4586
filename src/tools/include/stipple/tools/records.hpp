#pragma once
// A picked point's full record, read again from its source: the file's own coordinates in full
// double precision (not the float the GPU draws), lon/lat through PROJ where the CRS is known,
// and every attribute (extra bytes decoded by their descriptors). The built-in scene's points
// are generated again by index. Streamed tiles have no record to go back to: what the tile
// holds is shown instead.
#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <glm/vec3.hpp>

#include "stipple/io/geojson.hpp"
#include "stipple/io/las.hpp"
#include "stipple/io/procedural.hpp"
#include "stipple/pointcloud/picking.hpp"
#include "stipple/pointcloud/point_cloud.hpp"

namespace stipple::tools {

struct PointRecord {
  bool from_source = false;           // read from the file or regenerated, not the packed GPU copy
  std::string source;                 // file name, "procedural scene" or "streamed tile"
  uint64_t index = 0;                 // record index in that file
  glm::dvec3 position{0.0};           // source CRS coordinates (lon/lat for geographic files)
  glm::dvec3 local{0.0};              // the viewer's local source frame (ENU metres for lon/lat)
  std::optional<glm::dvec3> lon_lat;  // lon, lat (degrees), ellipsoidal height
  // Attribute names and values in record order (numbers as numbers).
  std::vector<std::pair<std::string, io::GeoValue>> fields;
};

// What a PickHit leads back to. `cloud` is the picked scene's cloud (null for tilesets);
// `scene` its procedural parameters when generated. Throws stipple::Error when the file cannot
// be read again.
struct RecordSource {
  const pc::PointCloud* cloud = nullptr;
  std::optional<io::SceneParams> scene;
  io::Crs crs;  // of the first input (or the scene's)
};
PointRecord read_point_record(const RecordSource& source, const pc::PickHit& hit);

// Decodes extra bytes attribute by attribute (scale and offset applied where the descriptor
// says so); undocumented bytes as hex.
std::vector<std::pair<std::string, io::GeoValue>> decode_extra_bytes(
    const std::vector<io::ExtraBytesDescriptor>& descriptors, const uint8_t* bytes, size_t size);

}  // namespace stipple::tools
