#pragma once
// glTF 2.0 binary (glb) point content for 3D Tiles 1.1: one mesh primitive with mode POINTS.
//
// Axes: glTF is Y-up and 3D Tiles 1.1 rotates glTF content from Y-up to Z-up at run time
// (x, y, z)_tile = (x, -z, y)_gltf, so positions and the node transform are stored Y-up:
// (x, y, z)_tile -> (x, z, -y)_gltf. The tile frame is the tileset's local ENU frame.
//
// Positions are relative to the tile: quantized UNSIGNED_SHORT (KHR_mesh_quantization) with
// the node's scale/translation when 65535 steps over the tile's extent are at least as fine as
// the input precision (steps of that precision, or wider where the extent needs it), else FLOAT
// relative to the tile centre (node translation).
// Attributes: COLOR_0 (normalized UNSIGNED_SHORT VEC3, linear as glTF defines it: the LAS sRGB
// bytes through the sRGB transfer function, 12 significant bits), _INTENSITY (UNSIGNED_SHORT),
// _CLASSIFICATION, _RETURN_NUMBER (UNSIGNED_BYTE), _GPS_TIME (FLOAT, seconds after the value in
// the primitive's extras.gpsTimeOffset, so float keeps sub-millisecond resolution within a tile).
// Sub-4-byte attributes get byteStride 4, as glTF requires for vertex attributes.
#include <cstdint>
#include <span>
#include <vector>

#include "stipple/tiler/tile_point.hpp"

namespace stipple::tiler {

// With Compression::Meshopt every buffer view is an EXT_meshopt_compression stream (mode
// ATTRIBUTES, the views' layout unchanged) and the points are in GPS time order (Morton order
// without GPS time).
std::vector<uint8_t> write_glb(std::span<const TilePoint> points, const ContentOptions& options);

// The points sorted along a Morton curve over their bounding box (10 bits an axis).
std::vector<TilePoint> morton_ordered(std::span<const TilePoint> points);

// True when u16 quantization over `extent` (metres, per axis max) keeps `precision`.
inline bool quantization_keeps(double extent, double precision) {
  return extent / 65535.0 <= precision;
}

}  // namespace stipple::tiler
