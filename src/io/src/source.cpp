#include "stipple/io/source.hpp"

#include "stipple/io/copc.hpp"
#include "stipple/io/ept.hpp"
#include "stipple/io/fetch.hpp"
#include "stipple/io/potree.hpp"
#include "stipple/io/tileset.hpp"

namespace stipple::io {

SourceFormat source_format(const std::string& uri) {
  if (is_copc_input(uri)) return SourceFormat::Copc;
  if (is_potree_input(uri)) return SourceFormat::Potree;  // cloud.js is not named .json
  if (is_ept_input(uri)) return SourceFormat::Ept;
  // Any other URL is read as a tileset: its JSON decides (a LAS URL says what it is there).
  if (is_url(uri) || is_tileset_uri(uri)) return SourceFormat::Tileset;
  return SourceFormat::Las;
}

const char* source_format_name(SourceFormat format) {
  switch (format) {
    case SourceFormat::Las:
      return "LAS/LAZ";
    case SourceFormat::Copc:
      return "COPC";
    case SourceFormat::Tileset:
      return "3D Tiles";
    case SourceFormat::Potree:
      return "Potree";
    case SourceFormat::Ept:
      return "EPT";
  }
  return "unknown";
}

}  // namespace stipple::io
