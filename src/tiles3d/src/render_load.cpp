#include "stipple/tiles3d/render_load.hpp"

#include <algorithm>
#include <initializer_list>
#include <map>

#include <glm/gtc/matrix_transform.hpp>

#include "stipple/core/error.hpp"
#include "stipple/core/log.hpp"
#include "stipple/io/content_summary.hpp"
#include "stipple/io/copc.hpp"
#include "stipple/io/ept.hpp"
#include "stipple/io/potree.hpp"
#include "stipple/math/geo.hpp"

namespace stipple::tiles3d {

glm::dmat4 world_from_tileset(const io::Tileset& ts) {
  const glm::dmat4 y_up(1, 0, 0, 0, 0, 0, -1, 0, 0, 1, 0, 0, 0, 0, 0, 1);
  // COPC and Potree are in their files' projected coordinates, whatever their magnitude.
  if (ts.tiles.empty() || ts.copc || ts.potree || ts.ept) return y_up;
  glm::dvec3 c = ts.tiles[0].box.center;
  if (glm::length(c) < 1e6) return y_up;  // a local frame already
  glm::dvec3 llh = geo::ecef_to_geodetic(c);
  glm::dmat3 enu = geo::enu_basis(llh.x, llh.y);
  glm::dmat4 local(glm::transpose(enu));  // ECEF -> ENU rotation
  local = local * glm::translate(glm::dmat4(1.0), -c);
  return y_up * local;
}

Aabb world_bounds(const io::Tileset& ts, const glm::dmat4& m) {
  Aabb box;
  if (ts.tiles.empty()) return box;
  if (ts.copc) {
    // The header's bounds: the octree's root cube is larger than the data (framing uses this).
    const io::LasHeader& h = ts.copc->header;
    for (int i = 0; i < 8; ++i) {
      glm::dvec3 p(i & 1 ? h.max.x : h.min.x, i & 2 ? h.max.y : h.min.y, i & 4 ? h.max.z : h.min.z);
      box.extend(glm::dvec3(m * glm::dvec4(p, 1.0)));
    }
    return box;
  }
  if (ts.potree || ts.ept) {
    // The points' bounds (Potree: position min/max; EPT: boundsConforming), not the cube.
    for (int i = 0; i < 8; ++i) {
      const glm::dvec3 lo = ts.potree ? ts.potree->data_min : ts.ept->data_min;
      const glm::dvec3 hi = ts.potree ? ts.potree->data_max : ts.ept->data_max;
      glm::dvec3 p(i & 1 ? hi.x : lo.x, i & 2 ? hi.y : lo.y, i & 4 ? hi.z : lo.z);
      box.extend(glm::dvec3(m * glm::dvec4(p, 1.0)));
    }
    return box;
  }
  const io::Obb& o = ts.tiles[0].box;
  for (int i = 0; i < 8; ++i) {
    glm::dvec3 p = o.center;
    for (int k = 0; k < 3; ++k) p += o.half_axes[k] * ((i >> k) & 1 ? 1.0 : -1.0);
    box.extend(glm::dvec3(m * glm::dvec4(p, 1.0)));
  }
  return box;
}

namespace {

void extend_by_obb(Aabb& box, const io::Obb& o, const glm::dmat4& m) {
  for (int i = 0; i < 8; ++i) {
    glm::dvec3 p = o.center;
    for (int k = 0; k < 3; ++k) p += o.half_axes[k] * ((i >> k) & 1 ? 1.0 : -1.0);
    box.extend(glm::dvec3(m * glm::dvec4(p, 1.0)));
  }
}

}  // namespace

Aabb drawable_world_bounds(const io::Tileset& ts, const glm::dmat4& m, const io::Fetcher& fetcher,
                           std::string* warning, std::set<std::string>* kinds,
                           size_t max_contents) {
  const Aabb root = world_bounds(ts, m);
  if (ts.copc || ts.potree || ts.ept) return root;  // every node is points
  std::map<std::string, size_t> not_drawn;
  Aabb points;
  size_t read = 0;
  // Tiles are stored parents first: index order is breadth first enough for a sample.
  for (const io::Tile& t : ts.tiles) {
    for (const std::string& uri : t.contents) {
      if (read >= max_contents) break;
      ++read;
      const io::ContentSummary s = io::summarize_content(uri, fetcher);
      if (!s.error.empty()) continue;  // its tile reports the error when it loads
      if (s.drawable)
        extend_by_obb(points, t.box, m);
      else if (s.type != "json")
        ++not_drawn[s.type];
    }
    if (read >= max_contents) break;
  }
  if (not_drawn.empty()) return root;
  if (kinds)
    for (const auto& [type, n] : not_drawn) kinds->insert(io::describe_content_type(type));
  if (warning) {
    std::string what;
    for (const auto& [type, n] : not_drawn)
      what += fmt::format("{}{} {}", what.empty() ? "" : ", ", n, io::describe_content_type(type));
    *warning = fmt::format(
        "{}: of the first {} contents, {} {} not drawn (stipple draws points only){}", ts.uri, read,
        what, not_drawn.size() == 1 && not_drawn.begin()->second == 1 ? "is" : "are",
        points.empty() ? "" : "; the view frames the point content");
  }
  return points.empty() ? root : points;
}

namespace {

// A per-point scalar attribute under any of the names writers use (pnts batch tables: INTENSITY;
// glb: _INTENSITY, or the EXT_structural_metadata property name); null when absent.
const std::vector<double>* scalar_attribute(const io::PointContent& content,
                                            std::initializer_list<const char*> names) {
  for (const char* name : names) {
    auto it = content.attributes.find(name);
    if (it != content.attributes.end() && it->second.components == 1 &&
        it->second.values.size() == content.point_count)
      return &it->second.values;
  }
  return nullptr;
}

uint32_t clamp_to(double v, uint32_t max) {
  return v > 0 ? uint32_t(std::min(v, double(max))) : 0u;
}

}  // namespace

uint64_t append_content(pc::PointCloud& cloud, const io::PointContent& content,
                        const glm::dmat4& tile_transform, const glm::dmat4& world_from_tileset) {
  if (content.point_count == 0 || content.splats) return 0;  // splats: not points
  // LAS attributes carried by the tile drive the intensity, classification and return colour
  // modes, as for LAS input.
  const auto* intensity =
      scalar_attribute(content, {"intensity", "INTENSITY", "_INTENSITY", "Intensity"});
  const auto* classification = scalar_attribute(
      content, {"classification", "CLASSIFICATION", "_CLASSIFICATION", "Classification"});
  const auto* returns = scalar_attribute(
      content, {"return_number", "RETURN_NUMBER", "_RETURN_NUMBER", "ReturnNumber"});
  const auto* return_count = scalar_attribute(
      content, {"number_of_returns", "NUMBER_OF_RETURNS", "_NUMBER_OF_RETURNS", "NumberOfReturns"});
  glm::dmat4 m = world_from_tileset * tile_transform;
  pc::PointChunk chunk;
  chunk.origin = glm::dvec3(m * glm::dvec4(content.center, 1.0));
  glm::dmat3 linear(m);  // offsets from the centre only need the linear part
  chunk.vertices.reserve(content.point_count);
  uint64_t transparent = 0;
  bool translucent = false;
  for (size_t i = 0; i < content.point_count; ++i) {
    uint32_t rgba = content.rgba.empty() ? pc::pack_rgba(220, 220, 220) : content.rgba[i];
    // The file's alpha where it gives one (PointContent::alpha), else opaque. Fully transparent
    // points (and those a MASK material cut) show in no mode: left out.
    if (!content.alpha)
      rgba |= 0xff000000u;
    else if ((rgba >> 24) == 0) {
      ++transparent;
      continue;
    }
    translucent = translucent || (rgba >> 24) < 255;
    glm::dvec3 p = linear * glm::dvec3(content.positions[i]);
    const uint32_t attributes =
        pc::pack_attributes(uint16_t(intensity ? clamp_to((*intensity)[i], 65535) : 0),
                            uint8_t(classification ? clamp_to((*classification)[i], 255) : 0),
                            uint8_t(returns ? clamp_to((*returns)[i], 15) : 0),
                            uint8_t(return_count ? clamp_to((*return_count)[i], 15) : 0));
    chunk.vertices.push_back({float(p.x), float(p.y), float(p.z), rgba, attributes});
    glm::dvec3 world = chunk.origin + p;
    chunk.bounds.extend(world);
    cloud.world_bounds.extend(world);
    cloud.source_bounds.extend(glm::dvec3(
        tile_transform * glm::dvec4(content.center + glm::dvec3(content.positions[i]), 1.0)));
  }
  cloud.point_count += chunk.vertices.size();
  pc::CloudAttributes& a = cloud.attributes;
  a.has_rgb = a.has_rgb || !content.rgba.empty();
  a.has_intensity = a.has_intensity || intensity;
  a.has_classification = a.has_classification || classification;
  a.has_returns = a.has_returns || returns;
  a.has_translucent = a.has_translucent || translucent;
  if (!chunk.vertices.empty()) cloud.chunks.push_back(std::move(chunk));
  return transparent;
}

RenderLoadResult load_tileset_for_render(const std::string& uri, const RenderLoadOptions& options) {
  io::TilesetOptions ts_options = options.streamer.tileset;
  ts_options.fetch = options.streamer.fetch;
  auto tileset = std::make_shared<io::Tileset>(
      options.streamer.fetcher ? io::load_tileset(uri, options.streamer.fetcher, ts_options)
                               : io::load_tileset(uri, ts_options));
  RenderLoadResult out;
  StreamerOptions streamer_options = options.streamer;
  for (const auto& e : tileset->errors) out.errors.push_back({0, e});
  for (const auto& w : tileset->warnings) out.warnings.push_back({0, w});
  View view;
  view.width = options.width;
  view.height = options.height;
  view.world_from_tileset = world_from_tileset(*tileset);
  if (options.camera) {
    view.camera = *options.camera;
  } else {
    const io::Fetcher fetcher = options.streamer.fetcher
                                    ? options.streamer.fetcher
                                    : io::Fetcher([&](const std::string& u) {
                                        return io::fetch(u, options.streamer.fetch);
                                      });
    const Aabb box =
        drawable_world_bounds(*tileset, view.world_from_tileset, fetcher, &out.not_drawn_warning,
                              &streamer_options.not_drawn_warned);
    view.camera = frame_box(box, double(options.width) / options.height, options.azimuth,
                            options.elevation, options.fov);
  }
  TileStreamer streamer(tileset, streamer_options);
  const Selection* selection = nullptr;
  for (size_t i = 0; i < options.max_updates; ++i) {
    selection = &streamer.update(view);
    if (streamer.idle()) break;
    streamer.wait_for_progress();
  }
  for (auto& e : streamer.take_errors()) out.errors.push_back(std::move(e));
  for (auto& w : streamer.take_warnings()) out.warnings.push_back(std::move(w));
  out.camera = view.camera;
  out.stats = streamer.stats();
  out.budget_limited = selection->budget_limited;
  out.sse_threshold = selection->sse_threshold;
  if (out.budget_limited && selection->render.empty())
    STIPPLE_WARN(
        "{}: the memory budget ({:.1f} MiB) is smaller than the coarsest tiles this view "
        "needs: nothing is drawn",
        uri, double(options.streamer.traversal.memory_budget) / (1 << 20));
  else if (out.budget_limited)
    STIPPLE_WARN(
        "{}: the memory budget ({:.1f} MiB) limited detail: screen-space error {:.1f} px "
        "instead of {:.1f}",
        uri, double(options.streamer.traversal.memory_budget) / (1 << 20), out.sse_threshold,
        options.streamer.traversal.max_sse);
  for (uint32_t t : selection->render) {
    const auto* contents = streamer.content(t);
    if (!contents) continue;
    for (const auto& c : *contents)
      append_content(out.cloud, c, tileset->tiles[t].transform, view.world_from_tileset);
    ++out.tiles_rendered;
  }
  pc::finish_cloud(out.cloud);
  STIPPLE_INFO(
      "{}: {} tiles read ({} external tilesets, {} subtrees), {} rendered, {} points, "
      "{} errors",
      uri, tileset->tiles.size(), tileset->external_tilesets, tileset->subtrees, out.tiles_rendered,
      out.cloud.point_count, out.errors.size());
  return out;
}

}  // namespace stipple::tiles3d
