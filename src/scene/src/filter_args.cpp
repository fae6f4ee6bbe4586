#include "stipple/scene/filter_args.hpp"

#include <utility>

#include "stipple/io/geojson.hpp"

namespace stipple::scene {

pc::PointFilter make_filter(const FilterArgs& args) {
  return args.filter;
}

pc::ClipRegion make_region(const FilterArgs& args) {
  pc::ClipRegion region;
  region.boxes = args.boxes;
  region.planes = args.planes;
  region.mode = args.mode;
  for (const std::string& file : args.polygon_files)
    for (io::GeoPolygon& p : io::read_geojson_polygons(file))
      region.polygons.push_back({std::move(p.rings), p.min_z, p.max_z});
  return region;
}

}  // namespace stipple::scene
