#include "stipple/tiler/splat_merge.hpp"

#include <algorithm>
#include <cmath>
#include <queue>

#include <glm/gtc/quaternion.hpp>

namespace stipple::tiler {

void symmetric_eigen(const glm::dmat3& input, glm::dvec3& values, glm::dmat3& vectors) {
  // Cyclic Jacobi rotations; a[c][r] is glm's column-major element (r, c), symmetric here.
  double a[3][3], v[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) a[r][c] = 0.5 * (input[c][r] + input[r][c]);
  for (int sweep = 0; sweep < 32; ++sweep) {
    const double off = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
    const double diag = a[0][0] * a[0][0] + a[1][1] * a[1][1] + a[2][2] * a[2][2];
    if (off <= 1e-30 * diag || off == 0.0) break;
    for (int p = 0; p < 2; ++p)
      for (int q = p + 1; q < 3; ++q) {
        if (a[p][q] == 0.0) continue;
        const double theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
        const double t =
            (theta >= 0 ? 1.0 : -1.0) / (std::abs(theta) + std::sqrt(theta * theta + 1));
        const double c = 1.0 / std::sqrt(t * t + 1), s = t * c;
        for (int k = 0; k < 3; ++k) {  // A <- A J
          const double akp = a[k][p], akq = a[k][q];
          a[k][p] = c * akp - s * akq;
          a[k][q] = s * akp + c * akq;
        }
        for (int k = 0; k < 3; ++k) {  // A <- J^T A
          const double apk = a[p][k], aqk = a[q][k];
          a[p][k] = c * apk - s * aqk;
          a[q][k] = s * apk + c * aqk;
        }
        for (int k = 0; k < 3; ++k) {  // V <- V J
          const double vkp = v[k][p], vkq = v[k][q];
          v[k][p] = c * vkp - s * vkq;
          v[k][q] = s * vkp + c * vkq;
        }
      }
  }
  int order[3] = {0, 1, 2};
  std::sort(order, order + 3, [&](int x, int y) { return a[x][x] < a[y][y]; });
  for (int i = 0; i < 3; ++i) {
    values[i] = a[order[i]][order[i]];
    for (int r = 0; r < 3; ++r) vectors[i][r] = v[r][order[i]];
  }
  if (glm::determinant(vectors) < 0) vectors[2] = -vectors[2];
}

namespace {

double area_of(const glm::vec3& s) {
  return double(s.x) * s.y + double(s.y) * s.z + double(s.z) * s.x;
}

glm::dmat3 covariance_of(const glm::vec3& scale, const glm::vec4& q) {
  const glm::dmat3 r = glm::mat3_cast(glm::dquat(q.w, q.x, q.y, q.z));
  const glm::dvec3 s2 = glm::dvec3(scale) * glm::dvec3(scale);
  return r * glm::dmat3(s2.x, 0, 0, 0, s2.y, 0, 0, 0, s2.z) * glm::transpose(r);
}

// 10 bits a coordinate, spread to every third bit.
uint32_t spread3(uint32_t v) {
  v &= 0x3ff;
  v = (v | (v << 16)) & 0x030000ff;
  v = (v | (v << 8)) & 0x0300f00f;
  v = (v | (v << 4)) & 0x030c30c3;
  v = (v | (v << 2)) & 0x09249249;
  return v;
}

}  // namespace

void merge_group(const io::SplatSet& in, const uint32_t* members, size_t count, io::SplatSet& out,
                 size_t o) {
  const size_t rc = in.rest_count();
  if (count == 1) {
    const size_t i = members[0];
    out.positions[o] = in.positions[i];
    out.scales[o] = in.scales[i];
    out.rotations[o] = in.rotations[i];
    out.opacities[o] = in.opacities[i];
    out.sh_dc[o] = in.sh_dc[i];
    for (size_t k = 0; k < rc; ++k) out.sh_rest[o * rc + k] = in.sh_rest[i * rc + k];
    return;
  }
  // Weights: opacity times area, with a floor so that a group of transparent splats still has
  // a defined mean.
  double total = 0;
  glm::dvec3 mean(0);
  for (size_t m = 0; m < count; ++m) {
    const size_t i = members[m];
    const double w = std::max(double(in.opacities[i]) * area_of(in.scales[i]), 1e-30);
    total += w;
    mean += w * glm::dvec3(in.positions[i]);
  }
  mean /= total;
  glm::dmat3 cov(0.0);
  glm::dvec3 dc(0);
  std::vector<glm::dvec3> rest(rc, glm::dvec3(0));
  for (size_t m = 0; m < count; ++m) {
    const size_t i = members[m];
    const double w = std::max(double(in.opacities[i]) * area_of(in.scales[i]), 1e-30);
    const glm::dvec3 d = glm::dvec3(in.positions[i]) - mean;
    cov += w * (covariance_of(in.scales[i], in.rotations[i]) + glm::outerProduct(d, d));
    dc += w * glm::dvec3(in.sh_dc[i]);
    for (size_t k = 0; k < rc; ++k) rest[k] += w * glm::dvec3(in.sh_rest[i * rc + k]);
  }
  cov /= total;
  glm::dvec3 values;
  glm::dmat3 vectors;
  symmetric_eigen(cov, values, vectors);
  const glm::dvec3 scale = glm::sqrt(glm::max(values, glm::dvec3(0.0)));
  const glm::dquat q = glm::normalize(glm::quat_cast(vectors));
  // Mass: the weights summed are opacity times area; spread over the merged area.
  double mass = 0;
  for (size_t m = 0; m < count; ++m)
    mass += double(in.opacities[members[m]]) * area_of(in.scales[members[m]]);
  const double area = area_of(glm::vec3(scale));
  out.positions[o] = glm::vec3(mean);
  out.scales[o] = glm::vec3(scale);
  out.rotations[o] = glm::vec4(float(q.x), float(q.y), float(q.z), float(q.w));
  out.opacities[o] = area > 0 ? float(std::min(1.0, mass / area)) : 1.0f;
  out.sh_dc[o] = glm::vec3(dc / total);
  for (size_t k = 0; k < rc; ++k) out.sh_rest[o * rc + k] = glm::vec3(rest[k] / total);
}

io::SplatSet morton_sorted(const io::SplatSet& in) {
  const size_t n = in.size(), rc = in.rest_count();
  glm::vec3 lo(1e30f), hi(-1e30f);
  for (const glm::vec3& p : in.positions) lo = glm::min(lo, p), hi = glm::max(hi, p);
  const glm::vec3 scale = 1023.0f / glm::max(hi - lo, glm::vec3(1e-12f));
  std::vector<std::pair<uint32_t, uint32_t>> keyed(n);
  for (size_t i = 0; i < n; ++i) {
    const glm::uvec3 c = glm::uvec3(glm::clamp((in.positions[i] - lo) * scale, 0.0f, 1023.0f));
    keyed[i] = {spread3(c.x) | spread3(c.y) << 1 | spread3(c.z) << 2, uint32_t(i)};
  }
  std::sort(keyed.begin(), keyed.end());
  io::SplatSet out;
  out.sh_degree = in.sh_degree;
  out.transform = in.transform;
  out.format = in.format;
  out.positions.resize(n);
  out.scales.resize(n);
  out.rotations.resize(n);
  out.opacities.resize(n);
  out.sh_dc.resize(n);
  out.sh_rest.resize(n * rc);
  for (size_t o = 0; o < n; ++o) {
    const size_t i = keyed[o].second;
    out.positions[o] = in.positions[i];
    out.scales[o] = in.scales[i];
    out.rotations[o] = in.rotations[i];
    out.opacities[o] = in.opacities[i];
    out.sh_dc[o] = in.sh_dc[i];
    for (size_t k = 0; k < rc; ++k) out.sh_rest[o * rc + k] = in.sh_rest[i * rc + k];
  }
  return out;
}

MergeResult merge_splats(const io::SplatSet& in, const glm::dvec3& cube_min, double cube_size,
                         size_t target) {
  MergeResult result;
  const size_t n = in.size();
  target = std::max<size_t>(target, 1);
  if (n <= target) {
    result.splats = in;
    return result;
  }
  // Positions on a 2^10 grid over the cube, sorted along the Morton curve: every octree cell
  // down to level 10 is then one range of the order.
  std::vector<std::pair<uint32_t, uint32_t>> keyed(n);
  const double to_grid = 1024.0 / cube_size;
  for (size_t i = 0; i < n; ++i) {
    uint32_t c[3];
    for (int k = 0; k < 3; ++k)
      c[k] =
          uint32_t(std::clamp((double(in.positions[i][k]) - cube_min[k]) * to_grid, 0.0, 1023.0));
    keyed[i] = {spread3(c[0]) | spread3(c[1]) << 1 | spread3(c[2]) << 2, uint32_t(i)};
  }
  std::sort(keyed.begin(), keyed.end());
  struct Cell {
    uint32_t begin, end;
    int level;
    bool operator<(const Cell& o) const { return end - begin < o.end - o.begin; }
  };
  // The sub-ranges of `c` one level down.
  auto children = [&](const Cell& c, std::vector<Cell>& kids) {
    kids.clear();
    const int shift = 3 * (10 - c.level - 1);
    uint32_t start = c.begin;
    for (uint32_t i = c.begin + 1; i <= c.end; ++i)
      if (i == c.end || (keyed[i].first >> shift) != (keyed[start].first >> shift)) {
        kids.push_back({start, i, c.level + 1});
        start = i;
      }
  };
  std::priority_queue<Cell> open;
  std::vector<Cell> done, kids;
  open.push({0, uint32_t(n), 0});
  size_t cells = 1;
  while (!open.empty()) {
    Cell c = open.top();
    if (c.end - c.begin == 1 || c.level == 10) {
      open.pop();
      done.push_back(c);
      continue;
    }
    children(c, kids);
    if (cells - 1 + kids.size() > target) break;  // the most populous cell cannot split: stop
    open.pop();
    cells += kids.size() - 1;
    for (const Cell& k : kids) open.push(k);
  }
  for (; !open.empty(); open.pop()) done.push_back(open.top());
  std::sort(done.begin(), done.end(),
            [](const Cell& a, const Cell& b) { return a.begin < b.begin; });

  io::SplatSet& out = result.splats;
  out.sh_degree = in.sh_degree;
  out.transform = in.transform;
  out.format = in.format;
  const size_t m = done.size(), rc = in.rest_count();
  out.positions.resize(m);
  out.scales.resize(m);
  out.rotations.resize(m);
  out.opacities.resize(m);
  out.sh_dc.resize(m);
  out.sh_rest.resize(m * rc);
  std::vector<uint32_t> members;
  double sum_sq = 0, merged = 0;
  for (size_t g = 0; g < m; ++g) {
    const Cell& c = done[g];
    members.clear();
    for (uint32_t i = c.begin; i < c.end; ++i) members.push_back(keyed[i].second);
    merge_group(in, members.data(), members.size(), out, g);
    if (members.size() > 1) {
      const double edge = cube_size / double(1u << c.level);
      sum_sq += double(members.size()) * edge * edge;
      merged += double(members.size());
    }
  }
  result.cell_size = merged > 0 ? std::sqrt(sum_sq / merged) : 0.0;
  return result;
}

}  // namespace stipple::tiler
