#pragma once
// What an input is, found once from its name (and, for a local .las/.laz, the COPC info VLR
// right after its header): the point files that are read whole, or one of the hierarchical
// sources that are streamed by their octree or tree (3D Tiles, COPC, Potree, EPT). Front ends
// classify each input once and hand the result down, so that later choices (the renderer, the
// streaming defaults, which loader opens it) never guess from the name again.
#include <cstdint>
#include <string>

namespace stipple::io {

enum class SourceFormat : uint8_t {
  Las,      // LAS/LAZ (not COPC), read whole
  Copc,     // a COPC file: its hierarchy streamed by range
  Tileset,  // a 3D Tiles tileset.json (path or URL; any other URL too)
  Potree,   // a Potree metadata.json (2.0) or cloud.js (1.x)
  Ept,      // an Entwine Point Tile ept.json
};

// The format of `uri` (a path or an http(s) URL). Reads the first bytes of a local .las/.laz
// file to tell COPC from plain LAS; anything else is decided by the name.
SourceFormat source_format(const std::string& uri);

// Whether the format is streamed through the tileset machinery (everything but plain LAS/LAZ).
constexpr bool is_streamed(SourceFormat format) {
  return format != SourceFormat::Las;
}

const char* source_format_name(SourceFormat format);

}  // namespace stipple::io
