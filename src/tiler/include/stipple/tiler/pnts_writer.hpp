#pragma once
// 3D Tiles 1.0 Point Cloud (pnts) content. Feature table: POINTS_LENGTH, RTC_CENTER (the tile
// centre in the tileset's local frame), POSITION_QUANTIZED with QUANTIZED_VOLUME_OFFSET/SCALE
// (relative to RTC_CENTER) when 16-bit steps keep the input precision, else POSITION (float32
// relative to RTC_CENTER); RGB. Batch table (one entry per point, binary): INTENSITY
// (UNSIGNED_SHORT), CLASSIFICATION, RETURN_NUMBER (UNSIGNED_BYTE), GPS_TIME (FLOAT seconds after
// the tile's earliest time, which the batch table's extras.offsets.GPS_TIME holds: glTF has no
// float64, so converters to 3D Tiles 1.1 refuse DOUBLE).
#include <cstdint>
#include <span>
#include <vector>

#include "stipple/tiler/tile_point.hpp"

namespace stipple::tiler {

std::vector<uint8_t> write_pnts(std::span<const TilePoint> points, const ContentOptions& options);

}  // namespace stipple::tiler
