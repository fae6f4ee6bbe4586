#include "tiler_content.hpp"

#include <mutex>
#include <vector>

#include "stipple/tiler/glb_writer.hpp"
#include "stipple/tiler/pnts_writer.hpp"
#include "tiler_files.hpp"

namespace stipple::tiler::detail {

namespace {

void record(Build& b, const NodeKey& key, std::span<const TilePoint> pts) {
  NodeInfo info;
  info.points = pts.size();
  info.content = bounds_of(pts);
  std::lock_guard lock(b.nodes_mutex);
  b.nodes[key] = info;
}

}  // namespace

void write_content(Build& b, const NodeKey& key, std::span<const TilePoint> pts) {
  record(b, key, pts);
  if (pts.empty()) return;
  std::vector<uint8_t> bytes;
  {
    Profiler::Scope encode(&b.prof, Step::Encode);
    bytes = b.opt.format == Format::Glb ? write_glb(pts, b.content) : write_pnts(pts, b.content);
  }
  const char* ext = b.opt.format == Format::Glb ? ".glb" : ".pnts";
  Profiler::Scope write(&b.prof, Step::Write, bytes.size());
  write_file(b.dir / "tiles" / (key.name() + ext), bytes.data(), bytes.size());
  b.written += pts.size();
}

}  // namespace stipple::tiler::detail
