#pragma once
// Readers for the 3D Gaussian splat formats in use (issue 46): INRIA PLY, PlayCanvas compressed
// PLY, antimatter15 .splat, Niantic SPZ (v1-v4), GaussianSplats3D .ksplat, PlayCanvas SOG and
// glTF KHR_gaussian_splatting (with its SPZ compression), all decoded to SplatSet's one form
// (splats.hpp says its conventions). Every size and offset a file states is checked before use:
// a damaged or hostile file is a stipple::Error naming the file and the defect, never a crash.
// Values are returned finite (a non-finite one is an error), scales non-negative.
//
// Axes are the file's own: no reader converts frames. SPZ's specification puts its data in
// its own axes (x right, y up, z back) where INRIA and PlayCanvas files keep the trainer's
// (x right, y down, z forward), and converting writers negate y and z: PlayCanvas's biker.spz
// is its biker.compressed.ply with y and z negated (the quaternion conjugated by the half turn
// about x). .splat and .ksplat store rotations real part first, as INRIA PLY does.
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>

#include "stipple/io/splats.hpp"

namespace stipple::io {

// Caps on what one file may make a reader allocate (the fuzz targets lower them).
struct SplatLimits {
  size_t max_splats = size_t(1) << 28;
  // Decompressed bytes of one gzip/zstd/zip payload.
  // 8 GiB; 3 GiB where size_t is 32 bits (WebAssembly), where 8 << 30 would wrap to 0.
  size_t max_inflated_bytes = sizeof(size_t) > 4 ? size_t(uint64_t(8) << 30) : size_t(3) << 30;
  // A splat tileset (read_splats of its tileset.json): the most splats of the cut it reads.
  size_t tileset_splats = 6'000'000;
};

// Whether a path or URL names a splat file. By extension: .splat, .ksplat, .spz and .sog are
// splats; a .ply is a splat file when its header (the first 64 KiB, read from the file; for a
// URL, fetched as a range) declares an INRIA splat vertex (f_dc_0, opacity, scale_0 and rot_0
// properties) or PlayCanvas's compressed layout (element chunk and a vertex of packed_position);
// other PLY files are point clouds. A .ply that cannot be read is not a splat file here (the
// point-cloud path then reports the error). meta.json of an unbundled SOG counts too, and a
// local .json file that is a tileset of KHR_gaussian_splatting content (a splat tileset, as
// `stipple tile` writes from splat files; URLs of tilesets are not looked into).
bool is_splat_path(std::string_view path_or_url);
// A splat tileset's tileset.json, local or a URL (its first 64 KiB fetched as a range): the
// front ends stream it (tiles3d's SplatTilesetPlugin) rather than read it whole.
bool is_splat_tileset_path(std::string_view path_or_url);

// Reads a file or an http(s) URL (through io::fetch) and decodes it. A splat tileset's
// tileset.json reads as one set: a cut through its tree of at most limits.tileset_splats splats,
// refined from the root, largest geometric error first (not for any view; its frame the root
// tile's, its transform the root's transform seen from glTF's Y-up).
SplatSet read_splats(const std::string& path_or_url, const SplatLimits& limits = {});

// Decodes a whole file's bytes. The format is found from the bytes (magic numbers, PLY header,
// gzip or zip signature) and, where the bytes do not say (.splat has no header), from `name`'s
// extension; `name` also names the file in errors.
SplatSet decode_splats(std::span<const uint8_t> bytes, std::string_view name,
                       const SplatLimits& limits = {});

// The splats of a glTF 2.0 binary: every mode-POINTS primitive with KHR_gaussian_splatting
// attributes (or its SPZ compression, KHR_gaussian_splatting_compression_spz_2 and the older
// KHR_spz_gaussian_splats_compression that CesiumJS reads). Positions, scales and rotations stay
// in the primitive's frame; the node's matrix goes to SplatSet::transform (glTF's Y-up frame:
// a consumer in 3D Tiles' Z-up frame applies the Y-up to Z-up rotation after it, as
// glb_points.hpp does). Several primitives under different node matrices are an error.
SplatSet decode_splats_glb(std::span<const uint8_t> glb, std::string_view name,
                           const SplatLimits& limits = {});

}  // namespace stipple::io
