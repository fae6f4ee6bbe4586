#pragma once
// A batch read by the LAS reader as tile content (the LAS/LAZ nodes of EPT and Potree 1.x):
// positions relative to their centre, colour (16-bit values scaled down unless the file's are
// 8-bit), intensity, classification, returns and GPS time. Private to the io module.
#include "stipple/io/pnts.hpp"
#include "stipple/io/point_batch.hpp"

namespace stipple::io {

PointContent content_from_batch(PointBatch& batch, int rgb_bits);

}  // namespace stipple::io
