#include "stipple/pointcloud/picking.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <glm/geometric.hpp>

#include "stipple/engine/registry.hpp"

namespace stipple::pc {

bool cone_may_hit(const Aabb& bounds, const PickRay& ray, double max_t) {
  if (bounds.empty()) return false;
  // A point p within the cone at distance t is within tan_radius * t of the axis, so the axis
  // passes through the box grown by that much. t is at most the farthest corner's distance.
  const glm::dvec3 far_corner =
      glm::max(glm::abs(bounds.min - ray.origin), glm::abs(bounds.max - ray.origin));
  const double grow = ray.tan_radius * std::min(glm::length(far_corner), max_t);
  const glm::dvec3 lo = bounds.min - grow, hi = bounds.max + grow;
  // Slab test of the axis (t in (0, max_t)) against the grown box.
  double t0 = 0.0, t1 = max_t;
  for (int i = 0; i < 3; ++i) {
    const double o = ray.origin[i], d = ray.direction[i];
    if (d == 0.0) {
      if (o < lo[i] || o > hi[i]) return false;
      continue;
    }
    double a = (lo[i] - o) / d, b = (hi[i] - o) / d;
    if (a > b) std::swap(a, b);
    t0 = std::max(t0, a);
    t1 = std::min(t1, b);
    if (t0 > t1) return false;
  }
  return true;
}

void pick_in_chunk(const pc::PointChunk& chunk, const Aabb& bounds, const PickRay& ray,
                   std::optional<PickHit>& best, const PickFilter* filter, bool numbered) {
  double best_t = best ? best->t : std::numeric_limits<double>::infinity();
  if (!cone_may_hit(bounds, ray, best_t)) return;
  const glm::dvec3 rel_origin = ray.origin - chunk.origin;
  const double tan2 = ray.tan_radius * ray.tan_radius;
  const bool filtering = filter && (filter->filter.active() || !filter->clip.empty());
  const bool extras = chunk.extras.size() == chunk.vertices.size();
  for (size_t i = 0; i < chunk.vertices.size(); ++i) {
    const auto& p = chunk.vertices[i];
    const glm::dvec3 w = glm::dvec3(p.x, p.y, p.z) - rel_origin;
    const double t = glm::dot(w, ray.direction);
    if (t <= 0 || t >= best_t) continue;
    const glm::dvec3 perpendicular = w - t * ray.direction;
    if (glm::dot(perpendicular, perpendicular) > tan2 * t * t) continue;
    if (filtering && !chunk_point_shown(chunk, i, filter->filter, filter->clip)) continue;
    best_t = t;
    PickHit hit;
    hit.point = chunk.origin + glm::dvec3(p.x, p.y, p.z);
    hit.t = t;
    hit.vertex = p;
    hit.has_extra = extras;
    if (extras) hit.extra = chunk.extras[i];
    hit.gps_origin = chunk.gps_origin;
    hit.source_point = numbered ? chunk.first_point + i : PickHit::kNoSourcePoint;
    best = hit;
  }
}

void add_scene_picker(Registry& main, PickFunction picker) {
  auto* pickers = main.try_resource<ScenePickers>();
  if (!pickers) pickers = &main.insert_resource(ScenePickers{});
  pickers->pickers.push_back(picker);
}

std::optional<PickHit> pick_scene(Registry& main, const PickRay& ray) {
  std::optional<PickHit> best;
  if (const auto* pickers = main.try_resource<ScenePickers>())
    for (PickFunction pick : pickers->pickers)
      if (auto hit = pick(main, ray); hit && (!best || hit->t < best->t)) best = hit;
  return best;
}

}  // namespace stipple::pc
