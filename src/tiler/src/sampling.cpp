#include "stipple/tiler/sampling.hpp"

#include <algorithm>
#include <cmath>

namespace stipple::tiler {

size_t grid_select(std::span<const TilePoint> points, const glm::dvec3& origin, double spacing,
                   size_t cap, std::vector<uint8_t>& selected) {
  const size_t n = points.size();
  selected.assign(n, 0);
  if (n == 0) return 0;
  // Open addressing: cell key -> best point so far. Sized by occupied cells, not points (a
  // surface occupies far fewer cells than it has points): grows at half load.
  size_t capacity = 1024;
  struct Slot {
    uint64_t key;  // 0: empty
    uint32_t index;
    float dist2;
  };
  thread_local std::vector<Slot> table;  // reused: no fresh pages per node
  table.assign(capacity, Slot{0, 0, 0});
  // Fibonacci hashing on the product's high bits: every key bit (x is in the top third) reaches
  // the slot index. (Bits 20.. of the product ignored x entirely: long probe chains.)
  int shift = 64 - 10;
  auto slot_of = [&](uint64_t key) { return size_t((key * 0x9E3779B97F4A7C15ull) >> shift); };
  const double inv = 1.0 / spacing;
  size_t count = 0;
  for (size_t i = 0; i < n; ++i) {
    const TilePoint& p = points[i];
    // Points lie in the node, so cell coordinates are >= 0 (up to rounding): truncation is the
    // floor, and the clamp only catches rounding and points outside a caller's node.
    const double f[3] = {(p.x - origin.x) * inv, (p.y - origin.y) * inv, (p.z - origin.z) * inv};
    uint64_t key = 1;
    float d2 = 0;
    for (int k = 0; k < 3; ++k) {
      const double g = std::clamp(f[k], 0.0, 2097151.0);
      const uint64_t c = uint64_t(g);
      const float d = float(g - double(c) - 0.5);
      d2 += d * d;
      key = (key << 21) | c;
    }
    if (2 * (count + 1) > capacity) {
      thread_local std::vector<Slot> old;
      old.assign(capacity * 2, Slot{0, 0, 0});
      old.swap(table);
      capacity *= 2;
      --shift;
      for (const Slot& s : old) {
        if (!s.key) continue;
        size_t h = slot_of(s.key);
        while (table[h].key != 0) h = (h + 1) & (capacity - 1);
        table[h] = s;
      }
    }
    size_t h = slot_of(key);
    while (table[h].key != 0 && table[h].key != key) h = (h + 1) & (capacity - 1);
    Slot& s = table[h];
    if (s.key == 0) {
      s = Slot{key, uint32_t(i), d2};
      ++count;
    } else if (d2 < s.dist2) {
      s.index = uint32_t(i), s.dist2 = d2;
    }
  }
  for (const Slot& s : table)
    if (s.key) selected[s.index] = 1;
  if (count <= cap) return count;
  // Too many occupied cells (volumetric data): keep an even subset of `cap`, in input order.
  size_t seen = 0, kept = 0;
  for (size_t i = 0; i < n; ++i) {
    if (!selected[i]) continue;
    size_t want = (seen + 1) * cap / count;
    ++seen;
    if (want > kept) {
      ++kept;
    } else {
      selected[i] = 0;
    }
  }
  return kept;
}

}  // namespace stipple::tiler
