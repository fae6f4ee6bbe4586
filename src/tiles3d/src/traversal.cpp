#include "stipple/tiles3d/traversal.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <optional>
#include <utility>

#include <glm/geometric.hpp>

namespace stipple::tiles3d {
namespace {

struct Planes {
  std::array<glm::dvec4, 5> p;  // left, right, bottom, top, near; inside when dot >= 0
};

Planes frustum(const View& view) {
  glm::dmat4 m = view.camera.view_projection(view.width / view.height);
  auto row = [&](int r) { return glm::dvec4(m[0][r], m[1][r], m[2][r], m[3][r]); };
  Planes out;
  out.p[0] = row(3) + row(0);
  out.p[1] = row(3) - row(0);
  out.p[2] = row(3) + row(1);
  out.p[3] = row(3) - row(1);
  // Reverse-Z with an infinite far plane: only the near plane, straight from the camera.
  glm::dvec3 f = view.camera.forward();
  out.p[4] = glm::dvec4(f, -glm::dot(f, view.camera.position + f * view.camera.near_plane));
  for (auto& plane : out.p) {
    double l = glm::length(glm::dvec3(plane));
    if (l > 0) plane /= l;
  }
  return out;
}

struct WorldBox {
  glm::dvec3 center;
  glm::dmat3 axes;
  double sphere = -1;
};

bool outside(const Planes& planes, const WorldBox& b) {
  for (const auto& p : planes.p) {
    glm::dvec3 n(p);
    double r = b.sphere >= 0 ? b.sphere
                             : std::abs(glm::dot(n, b.axes[0])) + std::abs(glm::dot(n, b.axes[1])) +
                                   std::abs(glm::dot(n, b.axes[2]));
    if (glm::dot(n, b.center) + p.w < -r) return true;
  }
  return false;
}

// What a used tile takes: resident bytes and drawn points.
struct Cost {
  uint64_t bytes = 0, points = 0;
};

// One depth-first pass at a given screen-space error threshold.
class Traversal {
 public:
  Traversal(const io::Tileset& ts, const View& view, const std::vector<TileState>& states,
            const TraversalOptions& options, double threshold, Selection& out,
            std::vector<double>* candidates)
      : ts_(ts),
        view_(view),
        states_(states),
        options_(options),
        threshold_(threshold),
        out_(out),
        candidates_(candidates),
        planes_(frustum(view)),
        tileset_from_world_(glm::inverse(view.world_from_tileset)),
        eye_(glm::dvec3(tileset_from_world_ * glm::dvec4(view.camera.position, 1.0))) {
    // Distances are measured in the tileset frame; its scale to the world is taken along x.
    scale_ = glm::length(glm::dvec3(view.world_from_tileset[0]));
  }

  // Returns whether what this tile wants drawn is resident (no hole where it is). `estimate`:
  // the size assumed for content never loaded (the nearest ancestor's known size).
  bool visit(uint32_t index, uint64_t estimate, uint64_t estimate_points) {
    const io::Tile& t = ts_.tiles[index];
    ++out_.visited;
    if (options_.frustum_cull && culled(t)) {
      ++out_.culled;
      return true;  // not visible: it cannot leave a hole
    }
    double d = t.box.distance(eye_) * scale_;
    double sse = screen_space_error(t.geometric_error, d, view_);
    const TileState& st = states_[index];
    const Cost cost{st.bytes > 0 ? st.bytes : estimate,
                    st.points > 0            ? st.points
                    : t.content_points > 0   ? t.content_points
                                             : estimate_points};
    if (t.pending && t.pending->brings_content()) {
      // The root of a subtree (or COPC page) not read yet: its content and children come with
      // it.
      expand(index, sse, d);
      return false;
    }
    const bool has_content = !t.contents.empty();
    const LoadState state = st.state;
    const bool ready = !has_content || state == LoadState::Loaded || state == LoadState::Failed;
    const bool refinable = !t.children.empty() || t.pending != nullptr;
    if (candidates_ && refinable && sse > options_.max_sse) candidates_->push_back(sse);
    const bool refine = refinable && sse > threshold_;
    if (!refine) {
      want(index, sse, d, cost);
      return ready;
    }
    // External tilesets not read yet are children that are not ready.
    auto visit_children = [&] {
      bool all = true;
      for (uint32_t c : t.children) all &= visit(c, cost.bytes, cost.points);
      if (t.pending) {
        expand(index, sse, d);
        all = false;
      }
      return all;
    };
    if (t.refine == io::Refine::Add) {
      want(index, sse, d, cost);
      bool children_ready = visit_children();
      return ready && children_ready;
    }
    // REPLACE: children replace this tile only once all of them are ready; until then this
    // tile (if resident) is drawn instead and the children keep loading.
    size_t render_mark = out_.render.size();
    bool children_ready = visit_children();
    if (children_ready) return true;
    if (has_content && state == LoadState::Loaded) {
      out_.render.resize(render_mark);  // drop the partial children
      out_.render.push_back(index);
      use(index, cost);
      return true;
    }
    if (has_content && state != LoadState::Failed) request(index, sse, d, cost);
    return false;
  }

  // Bytes the used tiles need resident and their points, each tile counted once.
  void footprint(uint64_t* bytes, uint64_t* points) {
    std::sort(costs_.begin(), costs_.end(),
              [](const auto& a, const auto& b) { return a.first < b.first; });
    *bytes = *points = 0;
    for (size_t i = 0; i < costs_.size(); ++i)
      if (i == 0 || costs_[i].first != costs_[i - 1].first) {
        *bytes += costs_[i].second.bytes;
        *points += costs_[i].second.points;
      }
  }

 private:
  const io::Tileset& ts_;
  const View& view_;
  const std::vector<TileState>& states_;
  const TraversalOptions& options_;
  double threshold_;
  Selection& out_;
  std::vector<double>* candidates_;  // SSEs of tiles refined past max_sse (thresholds to try)
  std::vector<std::pair<uint32_t, Cost>> costs_;  // (used tile, its cost)
  Planes planes_;
  glm::dmat4 tileset_from_world_;
  glm::dvec3 eye_;
  double scale_ = 1;

  bool culled(const io::Tile& t) const {
    WorldBox b;
    glm::dmat3 linear(view_.world_from_tileset);
    b.center = glm::dvec3(view_.world_from_tileset * glm::dvec4(t.box.center, 1.0));
    b.axes = linear * t.box.half_axes;
    if (t.box.sphere_radius >= 0) b.sphere = t.box.sphere_radius * scale_;
    return outside(planes_, b);
  }
  void use(uint32_t index, Cost cost) {
    out_.used.push_back(index);
    costs_.emplace_back(index, cost);
  }
  void want(uint32_t index, double sse, double d, Cost cost) {
    const io::Tile& t = ts_.tiles[index];
    if (t.contents.empty()) return;
    LoadState s = states_[index].state;
    if (s == LoadState::Loaded) {
      out_.render.push_back(index);
      use(index, cost);
    } else if (s != LoadState::Failed) {
      request(index, sse, d, cost);
    }
  }
  void request(uint32_t index, double sse, double d, Cost cost) {
    out_.loads.push_back({index, sse, d});
    use(index, cost);
  }
  void expand(uint32_t index, double sse, double d) { out_.expands.push_back({index, sse, d}); }
};

// Most important first (SSE, then distance); a tile listed twice keeps its first entry.
void order(std::vector<LoadRequest>& requests, size_t tiles) {
  std::sort(requests.begin(), requests.end(), [](const LoadRequest& a, const LoadRequest& b) {
    if (a.sse != b.sse) return a.sse > b.sse;
    return a.distance < b.distance;
  });
  std::vector<bool> seen(tiles);
  std::erase_if(requests, [&](const LoadRequest& r) {
    if (seen[r.tile]) return true;
    seen[r.tile] = true;
    return false;
  });
}

}  // namespace

double screen_space_error(double geometric_error, double distance, const View& view) {
  if (distance <= 0) return std::numeric_limits<double>::infinity();
  double f = view.height / (2.0 * std::tan(view.camera.fov_y * 0.5));
  return geometric_error * f / distance;
}

Selection select_tiles(const io::Tileset& tileset, const View& view,
                       const std::vector<TileState>& states, const TraversalOptions& options,
                       uint64_t frame) {
  Selection out;
  if (tileset.tiles.empty() || states.size() != tileset.tiles.size()) return out;
  // Content never loaded is assumed to be as large as the nearest ancestor's, or else the mean
  // of the sizes known: point tiles hold similar point counts at every level.
  uint64_t known = 0, known_count = 0, known_points = 0, points_count = 0;
  for (const auto& s : states) {
    if (s.bytes > 0) known += s.bytes, ++known_count;
    if (s.points > 0) known_points += s.points, ++points_count;
  }
  const uint64_t estimate = known_count ? known / known_count : 0;
  const uint64_t estimate_points = points_count ? known_points / points_count : 0;
  auto run = [&](double threshold, std::vector<double>* candidates) {
    Selection s;
    s.sse_threshold = threshold;
    Traversal traversal(tileset, view, states, options, threshold, s, candidates);
    traversal.visit(0, estimate, estimate_points);
    traversal.footprint(&s.footprint, &s.footprint_points);
    return s;
  };
  auto within_budget = [&](const Selection& s) {
    return s.footprint <= options.memory_budget &&
           (options.point_budget == 0 || s.footprint_points <= options.point_budget);
  };
  std::vector<double> candidates;
  out = run(options.max_sse, &candidates);
  if (!within_budget(out)) {
    // Over budget: the lowest threshold whose selection fits. Refinement decisions only change
    // where the threshold passes a refined tile's SSE, so those are the thresholds to try; the
    // footprint shrinks as the threshold grows.
    std::sort(candidates.begin(), candidates.end());
    candidates.erase(std::unique(candidates.begin(), candidates.end()), candidates.end());
    std::optional<Selection> best;
    size_t lo = 0, hi = candidates.size();
    while (lo < hi) {
      size_t mid = (lo + hi) / 2;
      Selection s = run(candidates[mid], nullptr);
      if (within_budget(s)) {
        best = std::move(s);
        hi = mid;
      } else {
        lo = mid + 1;
      }
    }
    if (!best) {
      // Not even the coarsest tiles fit: nothing is requested (it could not be kept).
      best.emplace();
      best->visited = out.visited;
      best->sse_threshold = std::numeric_limits<double>::infinity();
    }
    out = std::move(*best);
    out.budget_limited = true;
  }
  order(out.loads, states.size());
  order(out.expands, states.size());
  std::vector<bool> wanted(states.size());
  for (uint32_t t : out.used) wanted[t] = true;
  for (uint32_t i = 0; i < states.size(); ++i)
    if (states[i].state == LoadState::Loading && !wanted[i]) out.cancel.push_back(i);
  // Evict least recently used tiles not wanted this frame until the budget holds.
  std::vector<TileState> now = states;
  for (uint32_t t : out.used) now[t].last_used = frame;
  bool fits = false;
  out.evict = make_room(now, 0, options.memory_budget, frame, &fits);
  return out;
}

std::vector<uint32_t> make_room(const std::vector<TileState>& states, uint64_t incoming,
                                uint64_t budget, uint64_t frame, bool* fits) {
  uint64_t resident = 0;
  std::vector<uint32_t> candidates;
  for (uint32_t i = 0; i < states.size(); ++i) {
    if (states[i].state != LoadState::Loaded) continue;
    resident += states[i].bytes;
    if (states[i].last_used < frame) candidates.push_back(i);
  }
  std::vector<uint32_t> evict;
  if (resident + incoming <= budget) {
    if (fits) *fits = true;
    return evict;
  }
  std::sort(candidates.begin(), candidates.end(), [&](uint32_t a, uint32_t b) {
    return states[a].last_used != states[b].last_used ? states[a].last_used < states[b].last_used
                                                      : a > b;  // deeper (later) tiles first
  });
  for (uint32_t c : candidates) {
    if (resident + incoming <= budget) break;
    evict.push_back(c);
    resident -= states[c].bytes;
  }
  if (fits) *fits = resident + incoming <= budget;
  return evict;
}

}  // namespace stipple::tiles3d
