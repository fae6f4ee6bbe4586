#pragma once
// Grid subsampling of one octree node (Potree-style "spacing"): the node is covered by cells of
// edge `spacing`; from each occupied cell the point nearest the cell centre is selected. The
// selection is capped at `cap` points (evenly thinned) so tiles stay small in volumetric data.
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "stipple/tiler/tile_point.hpp"

namespace stipple::tiler {

// selected[i] = 1 for the chosen points; returns how many.
size_t grid_select(std::span<const TilePoint> points, const glm::dvec3& origin, double spacing,
                   size_t cap, std::vector<uint8_t>& selected);

}  // namespace stipple::tiler
