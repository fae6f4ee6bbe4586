#pragma once
// What a 3D Tiles content holds, read from its header alone (no point is decoded): its type by
// magic, the points it declares (pnts POINTS_LENGTH; glb/glTF: the POSITION counts of its point
// primitives) and whether stipple draws it. Local files and http(s) are read by byte range
// (fetch.hpp): the fixed header, then the JSON it announces; a server that ignores ranges costs
// a whole download. `stipple info` totals a tileset with it; render and view frame on the
// contents it finds to be points.
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "stipple/io/tileset.hpp"

namespace stipple::io {

struct ContentSummary {
  // "pnts", "glb", "gltf", "b3dm", "i3dm", "cmpt", "json" (an external tileset), "copc",
  // "geojson", "vctr", "geom" or "unknown".
  std::string type;
  uint64_t points = 0;            // declared by the header
  uint64_t other_primitives = 0;  // glb/glTF primitives that are not points (meshes, lines)
  bool drawable = false;          // point content stipple draws
  std::string error;              // the header could not be read (then type may be "unknown")
};

// A readable name for a content type, for messages ("b3dm: batched 3D models").
std::string describe_content_type(const std::string& type);

// Never throws: a failure is ContentSummary::error.
ContentSummary summarize_content(const std::string& uri, const Fetcher& fetcher,
                                 uint64_t max_json_bytes = 64ull << 20);

// Summaries of many contents, read `threads` at a time (a progress bar on a terminal).
struct ContentTotals {
  uint64_t contents = 0;
  uint64_t points = 0;                        // declared by the drawable contents
  std::map<std::string, uint64_t> by_type;    // contents by type
  std::map<std::string, uint64_t> not_drawn;  // contents by type that stipple does not draw
  uint64_t other_primitives = 0;              // in glb/glTF contents
  std::vector<std::string> errors;            // headers that could not be read
};
ContentTotals summarize_contents(const std::vector<std::string>& uris, const Fetcher& fetcher,
                                 unsigned threads = 8);

}  // namespace stipple::io
