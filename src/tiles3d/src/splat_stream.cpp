#include "stipple/tiles3d/splat_stream.hpp"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "stipple/core/error.hpp"
#include "stipple/core/log.hpp"
#include "stipple/engine/camera.hpp"
#include "stipple/engine/engine.hpp"
#include "stipple/engine/viewport.hpp"
#include "stipple/io/fetch.hpp"
#include "stipple/tiles3d/render_load.hpp"
#include "stream_view.hpp"

namespace stipple::tiles3d {

namespace {

// glTF's Y-up frame to 3D Tiles' Z-up: (x, y, z) -> (x, -z, y).
const glm::dmat4 kYupToZup(1, 0, 0, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 0, 0, 1);

// MainStage::Update: one streamer update with the first camera; a new list of parts when the
// drawn tiles changed.
void update_splat_stream(Registry& main) {
  auto& s = main.resource<StreamedSplats>();
  const std::optional<View> view = stream_view(main, s.width, s.height, s.world_from_tileset);
  if (!view) return;
  const Selection& selection = s.streamer->update(*view);
  auto report = [&](const TileError& e, bool error) {
    if (!s.problems.insert(std::string(tile_problem_kind(e.message))).second) return;
    if (error)
      STIPPLE_WARN("{}", e.message);
    else
      STIPPLE_INFO("{}", e.message);
  };
  for (const auto& e : s.streamer->take_errors()) {
    report(e, true);
    ++s.errors;
  }
  for (const auto& w : s.streamer->take_warnings()) report(w, false);

  std::vector<uint32_t> drawn;
  uint64_t splats = 0;
  for (uint32_t t : selection.render) {
    const auto* contents = s.streamer->content(t);
    if (!contents) continue;
    uint64_t n = 0;
    for (const auto& c : *contents)
      if (c.splats) n += c.splats->size();
    if (n == 0) continue;
    drawn.push_back(t);
    splats += n;
  }
  if (drawn != s.drawn) {
    s.drawn = std::move(drawn);
    s.parts.clear();
    for (uint32_t t : s.drawn)
      for (const auto& c : *s.streamer->content(t))
        if (c.splats && c.splats->size() > 0) s.parts.push_back(c.splats);
    ++s.generation;
  }
  s.drawn_tiles = uint32_t(s.drawn.size());
  s.drawn_splats = splats;
  s.resident_tiles = 0;
  for (const auto& st : s.streamer->states())
    if (st.state == LoadState::Loaded) ++s.resident_tiles;
  const StreamerStats stats = s.streamer->stats();
  s.resident_bytes = stats.resident_bytes;
  s.budget_limited = stats.budget_limited;
  s.sse_threshold = stats.sse_threshold;
  s.idle = s.streamer->idle();
  ++s.frames;
}

}  // namespace

io::SplatSet splats_in_root_frame(const io::SplatSet& splats, const glm::dmat4& tile_transform,
                                  const glm::dmat4& root_transform, std::string_view name) {
  // Node matrix, Y-up to Z-up, the tile's chain relative to the root's, back to Y-up.
  const glm::dmat4 m = glm::inverse(kYupToZup) * glm::inverse(root_transform) * tile_transform *
                       kYupToZup * splats.transform;
  const glm::dmat3 linear(m);
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r)
      if (std::abs(linear[c][r] - (c == r ? 1.0 : 0.0)) > 1e-9)
        fail("{}: the tile turns or scales its splats relative to the root, which is not supported",
             name);
  io::SplatSet out = splats;
  const glm::dvec3 offset(m[3]);
  for (glm::vec3& p : out.positions) p = glm::vec3(glm::dvec3(p) + offset);
  out.transform = glm::dmat4(1.0);
  return out;
}

void SplatTilesetPlugin::build(Engine& engine) {
  Registry& main = engine.main();
  io::TilesetOptions ts_options = streamer.tileset;
  ts_options.fetch = streamer.fetch;
  const io::Fetcher fetcher = [&ts_options](const std::string& u) {
    return io::fetch(u, ts_options.fetch);
  };
  auto tileset = std::make_shared<io::Tileset>(
      io::load_tileset(uri, io::SourceFormat::Tileset, fetcher, ts_options));
  for (const auto& w : tileset->warnings) STIPPLE_WARN("{}", w);
  for (const auto& e : tileset->errors) STIPPLE_WARN("{}", e);
  if (tileset->tiles.empty()) fail("{}: the tileset has no tiles", uri);
  StreamedSplats s;
  s.tileset = tileset;
  s.transform = glm::inverse(kYupToZup) * tileset->tiles[0].transform * kYupToZup;
  s.world_bounds = tiles3d::world_bounds(*tileset, s.world_from_tileset);
  s.width = width;
  s.height = height;
  StreamerOptions options = streamer;
  // On the worker: into the root's frame, so the main thread only concatenates.
  options.prepare = [root = tileset->tiles[0].transform](uint32_t tile, const glm::dmat4& transform,
                                                         std::vector<io::PointContent>& contents) {
    for (auto& c : contents) {
      if (!c.splats) continue;
      c.splats = std::make_shared<const io::SplatSet>(
          splats_in_root_frame(*c.splats, transform, root, fmt::format("tile {}", tile)));
    }
    return PreparedTile{};
  };
  s.streamer = std::make_shared<TileStreamer>(tileset, std::move(options));
  STIPPLE_INFO("{}: {} tiles of splats, streaming (budget {:.1f} MiB{})", uri,
               tileset->tiles.size(), double(streamer.traversal.memory_budget) / (1 << 20),
               streamer.traversal.point_budget
                   ? fmt::format(", {} splats", streamer.traversal.point_budget)
                   : "");
  main.insert_resource(std::move(s));
  engine.add_system(MainStage::Update, update_splat_stream, "update_splat_stream");
}

}  // namespace stipple::tiles3d
