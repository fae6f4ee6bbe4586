#include "stipple/io/procedural.hpp"

#include <algorithm>
#include <cmath>

namespace stipple::io {
namespace {

constexpr double kBlock = 60.0;       // town block pitch, metres
constexpr double kRoad = 10.0;        // road width between blocks
constexpr double kTreeCell = 9.0;     // one tree candidate per cell
constexpr double kLineSpacing = 0.5;  // scan-line spacing scales with density below

uint64_t mix(uint64_t x) {
  // splitmix64 finaliser: a cheap, well-distributed hash.
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}
double unit(uint64_t h) {
  return double(h >> 11) * (1.0 / 9007199254740992.0);
}
double hash2(int64_t x, int64_t y, uint64_t seed) {
  return unit(mix(uint64_t(x) * 0x632be59bd9b4e019ull ^ mix(uint64_t(y) ^ seed)));
}

double value_noise(double x, double y, uint64_t seed) {
  double fx = std::floor(x), fy = std::floor(y);
  int64_t ix = int64_t(fx), iy = int64_t(fy);
  double tx = x - fx, ty = y - fy;
  tx = tx * tx * (3 - 2 * tx);
  ty = ty * ty * (3 - 2 * ty);
  double a = hash2(ix, iy, seed), b = hash2(ix + 1, iy, seed);
  double c = hash2(ix, iy + 1, seed), d = hash2(ix + 1, iy + 1, seed);
  return (a + (b - a) * tx) + ((c + (d - c) * tx) - (a + (b - a) * tx)) * ty;
}

double terrain_height(double x, double y, uint64_t seed) {
  double h = 0, amp = 18.0, freq = 1.0 / 400.0;
  for (int o = 0; o < 5; ++o) {
    h += amp * (value_noise(x * freq, y * freq, seed + o) - 0.5);
    amp *= 0.45;
    freq *= 2.1;
  }
  return h;
}

struct Building {
  bool present = false;
  double x0, y0, x1, y1;  // footprint
  double base, height;    // ground level and eave height above it
  bool gabled;
  bool ridge_along_x;
  uint8_t r, g, b;
};

// The building on lot (qx, qy) of block (bx, by), present or not, whatever point is asked.
Building building_on_lot(double bx, double by, int qx, int qy, uint64_t seed) {
  Building bld;
  double inner = kBlock - kRoad;
  int64_t id_x = int64_t(bx) * 2 + qx, id_y = int64_t(by) * 2 + qy;
  double h0 = hash2(id_x, id_y, seed + 101);
  if (h0 < 0.25) return bld;  // empty lot
  double cell = inner / 2;
  double cx0 = bx * kBlock + kRoad + qx * cell, cy0 = by * kBlock + kRoad + qy * cell;
  double margin = 2.0 + 3.0 * hash2(id_x, id_y, seed + 102);
  bld.x0 = cx0 + margin;
  bld.y0 = cy0 + margin;
  bld.x1 = cx0 + cell - margin * (0.6 + 0.8 * hash2(id_x, id_y, seed + 103));
  bld.y1 = cy0 + cell - margin * (0.6 + 0.8 * hash2(id_x, id_y, seed + 104));
  bld.present = true;
  bld.base = terrain_height((bld.x0 + bld.x1) / 2, (bld.y0 + bld.y1) / 2, seed);
  bool tall = hash2(id_x, id_y, seed + 105) < 0.15;
  bld.height = tall ? 18.0 + 30.0 * hash2(id_x, id_y, seed + 106)
                    : 5.0 + 6.0 * hash2(id_x, id_y, seed + 106);
  bld.gabled = !tall && hash2(id_x, id_y, seed + 107) < 0.6;
  bld.ridge_along_x = (bld.x1 - bld.x0) > (bld.y1 - bld.y0);
  static constexpr uint8_t roofs[][3] = {{168, 72, 52},   {140, 60, 48}, {96, 96, 104},
                                         {120, 116, 110}, {70, 72, 80},  {180, 150, 120}};
  const auto& c = roofs[size_t(hash2(id_x, id_y, seed + 108) * 6) % 6];
  bld.r = c[0];
  bld.g = c[1];
  bld.b = c[2];
  return bld;
}

// The town occupies the middle of the scene; each block holds up to four buildings.
Building building_at(double x, double y, double size, uint64_t seed) {
  double town = size * 0.3;
  if (std::abs(x) > town || std::abs(y) > town) return {};
  double bx = std::floor(x / kBlock), by = std::floor(y / kBlock);
  double lx = x - bx * kBlock, ly = y - by * kBlock;
  if (lx < kRoad || ly < kRoad) return {};  // roads
  double inner = kBlock - kRoad;
  int qx = lx - kRoad < inner / 2 ? 0 : 1, qy = ly - kRoad < inner / 2 ? 0 : 1;
  Building bld = building_on_lot(bx, by, qx, qy, seed);
  if (!bld.present || x < bld.x0 || x > bld.x1 || y < bld.y0 || y > bld.y1) return {};
  return bld;
}

double roof_height(const Building& b, double x, double y) {
  if (!b.gabled) return b.base + b.height;
  double t = b.ridge_along_x ? (y - b.y0) / (b.y1 - b.y0) : (x - b.x0) / (b.x1 - b.x0);
  double span = b.ridge_along_x ? (b.y1 - b.y0) : (b.x1 - b.x0);
  return b.base + b.height + (1.0 - std::abs(2.0 * t - 1.0)) * span * 0.35;
}

struct Tree {
  bool present = false;
  double cx, cy, radius, crown_base, top;
  uint8_t r, g, b;
};

// Trees grow outside the town centre and along its edges; the nearest crown covering (x, y).
Tree tree_at(double x, double y, double size, uint64_t seed) {
  Tree best;
  int64_t gx = int64_t(std::floor(x / kTreeCell)), gy = int64_t(std::floor(y / kTreeCell));
  for (int64_t j = gy - 1; j <= gy + 1; ++j) {
    for (int64_t i = gx - 1; i <= gx + 1; ++i) {
      double cx = (double(i) + 0.2 + 0.6 * hash2(i, j, seed + 201)) * kTreeCell;
      double cy = (double(j) + 0.2 + 0.6 * hash2(i, j, seed + 202)) * kTreeCell;
      // Forest density: patches from noise, fewer inside the town.
      double forest = value_noise(cx / 150.0, cy / 150.0, seed + 203);
      double in_town = (std::abs(cx) < size * 0.3 && std::abs(cy) < size * 0.3) ? 0.35 : 0.0;
      if (hash2(i, j, seed + 204) > forest * 1.2 - in_town) continue;
      if (building_at(cx, cy, size, seed).present) continue;
      double radius = 2.0 + 2.5 * hash2(i, j, seed + 205);
      double d2 = (x - cx) * (x - cx) + (y - cy) * (y - cy);
      if (d2 > radius * radius) continue;
      double height = 8.0 + 14.0 * hash2(i, j, seed + 206);
      double ground = terrain_height(cx, cy, seed);
      double dome = std::sqrt(1.0 - d2 / (radius * radius));
      double top = ground + height - radius * 1.2 * (1.0 - dome);
      if (best.present && top < best.top) continue;
      best = {true,
              cx,
              cy,
              radius,
              ground + height * 0.35,
              top,
              uint8_t(30 + 40 * hash2(i, j, seed + 207)),
              uint8_t(80 + 60 * hash2(i, j, seed + 208)),
              uint8_t(25 + 30 * hash2(i, j, seed + 209))};
    }
  }
  return best;
}

}  // namespace

std::vector<SceneBuilding> scene_buildings(const SceneParams& params) {
  const double size = scene_size(params);
  const double town = size * 0.3;
  const uint64_t seed = mix(params.seed);
  std::vector<SceneBuilding> out;
  for (double by = std::floor(-town / kBlock); by * kBlock <= town; ++by)
    for (double bx = std::floor(-town / kBlock); bx * kBlock <= town; ++bx)
      for (int qy = 0; qy < 2; ++qy)
        for (int qx = 0; qx < 2; ++qx) {
          const Building b = building_on_lot(bx, by, qx, qy, seed);
          if (!b.present) continue;
          // Only what lies inside the town is built (building_at's first test).
          const Building at = building_at((b.x0 + b.x1) / 2, (b.y0 + b.y1) / 2, size, seed);
          if (!at.present || at.x0 != b.x0 || at.y0 != b.y0) continue;
          SceneBuilding sb;
          sb.min = glm::dvec2(params.origin) + glm::dvec2(b.x0, b.y0);
          sb.max = glm::dvec2(params.origin) + glm::dvec2(b.x1, b.y1);
          sb.base = params.origin.z + b.base;
          sb.height = b.height;
          sb.gabled = b.gabled;
          out.push_back(sb);
        }
  return out;
}

double scene_ground_height(const SceneParams& params, double x, double y) {
  return params.origin.z +
         terrain_height(x - params.origin.x, y - params.origin.y, mix(params.seed));
}

double scene_size(const SceneParams& params) {
  return std::max(50.0, std::sqrt(double(params.point_count) / params.density));
}

Aabb scene_bounds(const SceneParams& params) {
  double half = scene_size(params) / 2;
  Aabb box;
  box.min = params.origin + glm::dvec3(-half, -half, -40.0);
  box.max = params.origin + glm::dvec3(half, half, 110.0);
  return box;
}

void generate_scene(const SceneParams& params, uint64_t first, uint64_t count,
                    io::PointBatch& batch) {
  const double size = scene_size(params);
  const double half = size / 2;
  const uint64_t seed = mix(params.seed);
  // Parallel flight lines along x; points along a line at the survey's along-track spacing.
  const double spacing = 1.0 / std::sqrt(params.density);
  const double line_pitch = spacing * (kLineSpacing / 0.5);
  const uint64_t per_line = std::max<uint64_t>(1, uint64_t(size / spacing));
  const uint64_t lines = std::max<uint64_t>(1, uint64_t(size / line_pitch));
  const double swath = 400.0;  // metres per flight strip, for scan angles and source ids

  size_t base = batch.size();
  size_t n = base + count;
  batch.positions.resize(n);
  batch.rgb.resize(n);
  batch.intensity.resize(n);
  batch.classification.resize(n);
  batch.return_number.resize(n);
  batch.number_of_returns.resize(n);
  batch.scan_angle.resize(n);
  batch.gps_time.resize(n);
  batch.point_source_id.resize(n);
  batch.flags.resize(n);
  batch.user_data.resize(n);

  for (uint64_t k = 0; k < count; ++k) {
    uint64_t index = first + k;
    uint64_t h = mix(index ^ seed);
    uint64_t line = (index / per_line) % lines;
    uint64_t along = index % per_line;
    // Alternate flight directions, as a real survey flies back and forth.
    double t = (double(along) + unit(h)) / double(per_line);
    if (line & 1) t = 1.0 - t;
    double x = -half + t * size;
    double y = -half + (double(line) + unit(mix(h))) * line_pitch;
    y = std::min(y, half);

    double ground = terrain_height(x, y, seed);
    double z = ground;
    uint8_t cls = 2, r, g, b, ret = 1, rets = 1;
    double inten = 0.35;
    Building bld = building_at(x, y, size, seed);
    Tree tree = bld.present ? Tree{} : tree_at(x, y, size, seed);
    double u = unit(mix(h + 7));
    if (bld.present) {
      double roof = roof_height(bld, x, y);
      // A few pulses hit walls close to the footprint edge (scan angle is off-nadir).
      double edge = std::min({x - bld.x0, bld.x1 - x, y - bld.y0, bld.y1 - y});
      if (edge < 0.8 && u < 0.5) {
        z = bld.base + (roof - bld.base) * unit(mix(h + 9));
        r = 200, g = 190, b = 175;
      } else {
        z = roof;
        r = bld.r, g = bld.g, b = bld.b;
      }
      cls = 6;
      inten = 0.5;
    } else if (tree.present && z < tree.top) {
      // Canopy: first return in the crown; a third of pulses reach the ground as last return.
      rets = 2;
      if (u < 0.33) {
        ret = 2;
      } else {
        ret = 1;
        double depth = unit(mix(h + 11));
        z = tree.top - depth * depth * (tree.top - tree.crown_base) * 0.6;
        double shade =
            0.75 + 0.25 * (z - tree.crown_base) / std::max(1.0, tree.top - tree.crown_base);
        r = uint8_t(tree.r * shade), g = uint8_t(tree.g * shade), b = uint8_t(tree.b * shade);
        cls = 5;
        inten = 0.2;
      }
    }
    if (cls == 2) {
      bool road = std::abs(x) < size * 0.3 && std::abs(y) < size * 0.3 &&
                  (x - std::floor(x / kBlock) * kBlock < kRoad ||
                   y - std::floor(y / kBlock) * kBlock < kRoad);
      if (road) {
        cls = 11;
        double v = 70 + 20 * value_noise(x / 3, y / 3, seed + 301);
        r = g = uint8_t(v);
        b = uint8_t(v + 6);
        inten = 0.15;
      } else {
        double grass = value_noise(x / 40.0, y / 40.0, seed + 302);
        double fine = value_noise(x / 2.0, y / 2.0, seed + 303);
        r = uint8_t(70 + 60 * grass + 20 * fine);
        g = uint8_t(110 + 50 * (1 - grass) + 20 * fine);
        b = uint8_t(50 + 20 * fine);
        inten = 0.4;
      }
    }
    z += (unit(mix(h + 13)) - 0.5) * 0.04;  // ranging noise, a few centimetres

    size_t o = base + k;
    batch.positions[o] = params.origin + glm::dvec3(x, y, z);
    batch.rgb[o] = glm::u16vec3(r, g, b);
    batch.intensity[o] =
        uint16_t(std::clamp(inten + 0.1 * (unit(mix(h + 17)) - 0.5), 0.0, 1.0) * 65535.0);
    batch.classification[o] = cls;
    batch.return_number[o] = ret;
    batch.number_of_returns[o] = rets;
    double across = std::fmod(y + half, swath) / swath - 0.5;  // -0.5..0.5 across the strip
    batch.scan_angle[o] = float(across * 40.0);
    batch.gps_time[o] = 3.0e8 + double(index) * 1e-5;  // 100 kHz pulse rate, adjusted GPS time
    batch.point_source_id[o] = uint16_t(1 + uint64_t((y + half) / swath));
    batch.flags[o] = 0;
    batch.user_data[o] = 0;
  }
}

}  // namespace stipple::io
