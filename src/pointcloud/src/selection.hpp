#pragma once
// Streaming the points of LAS/LAZ/COPC inputs through a filter and clip region: shared by clip
// and profile. Private to the pointcloud module.
#include <algorithm>
#include <atomic>
#include <filesystem>
#include <memory>
#include <optional>
#include <vector>

#include "stipple/core/error.hpp"
#include "stipple/core/progress.hpp"
#include "stipple/io/las.hpp"
#include "stipple/math/aabb.hpp"
#include "stipple/math/geo.hpp"
#include "stipple/pointcloud/filters.hpp"

namespace stipple::pc::detail {

struct StreamOptions {
  std::vector<std::filesystem::path> inputs;
  PointFilter filter;
  ClipRegion region;
  std::optional<glm::dvec3> enu_origin;
  bool progress = true;
  const char* label = "clipping";
  std::atomic<uint64_t>* points_done = nullptr;
  size_t batch_points = 1 << 16;
};

struct StreamCounts {
  uint64_t points_read = 0;
  uint64_t files_skipped = 0;
};

// The region's boxes and polygons, as one box in the source frame; empty when unbounded.
inline Aabb region_bounds(const ClipRegion& region) {
  Aabb box;
  if (region.polygons.empty() && region.boxes.empty()) return box;
  for (const ClipBox& b : region.boxes)
    for (const glm::dvec3& c : b.corners()) box.extend(c);
  for (const ClipPolygon& p : region.polygons)
    for (const auto& ring : p.rings)
      for (const glm::dvec2& v : ring) {
        box.extend({v.x, v.y, std::max(p.min_z, -1e300)});
        box.extend({v.x, v.y, std::min(p.max_z, 1e300)});
      }
  return box;
}

inline bool overlaps(const Aabb& a, const glm::dvec3& min, const glm::dvec3& max) {
  return a.min.x <= max.x && a.max.x >= min.x && a.min.y <= max.y && a.max.y >= min.y &&
         a.min.z <= max.z && a.max.z >= min.z;
}

struct Selection {
  const StreamOptions& job;
  std::optional<geo::LocalEnu> enu;
  ClipRegion region;
  Aabb bounds;  // of the region's boxes and polygons (Inside only); empty: no skipping

  explicit Selection(const StreamOptions& j) : job(j), region(j.region) {
    if (region.mode == ClipMode::Highlight) region.mode = ClipMode::Inside;
    if (job.enu_origin) enu.emplace(*job.enu_origin);
    if (!enu && region.mode == ClipMode::Inside) bounds = region_bounds(region);
  }

  // The frame the region is in: ENU metres for lon/lat inputs, else the source's.
  glm::dvec3 local(const glm::dvec3& p) const { return enu ? enu->from_geodetic(p) : p; }

  // Whether a file can hold kept points at all (its header bounds against the region).
  bool may_keep(const io::LasHeader& h) const {
    return bounds.empty() || h.point_count == 0 || overlaps(bounds, h.min, h.max);
  }

  // keep[i] for every point of the batch; returns how many are kept.
  size_t select(const io::PointBatch& batch, std::vector<uint8_t>& keep) const {
    const size_t n = batch.size();
    keep.assign(n, 1);
    const bool filter = job.filter.active(), clip = !region.empty();
    if (!filter && !clip) return n;
    size_t kept = 0;
    for (size_t i = 0; i < n; ++i) {
      bool k = !filter || job.filter.accepts(batch, i);
      if (k && clip) {
        const glm::dvec3 p = enu ? enu->from_geodetic(batch.positions[i]) : batch.positions[i];
        k = region.keeps(p);
      }
      keep[i] = k;
      kept += k;
    }
    return kept;
  }
};

inline std::vector<io::LasHeader> read_headers(const StreamOptions& job) {
  if (job.inputs.empty()) fail("no input files");
  std::vector<io::LasHeader> headers;
  for (const auto& in : job.inputs) headers.push_back(io::read_las_header(in));
  return headers;
}

// Hands every batch of kept points to `sink(batch, selection, header)` (the header of the
// reader, which knows the file's RGB bits); the batch's positions are in
// the source frame (lon/lat for geographic inputs: selection.local() maps them).
template <typename Sink>
void stream_inputs(const StreamOptions& job, const std::vector<io::LasHeader>& headers,
                   StreamCounts& result, Sink sink) {
  const Selection selection(job);
  uint64_t total = 0;
  for (const auto& h : headers) total += h.point_count;
  std::unique_ptr<Progress> progress;
  if (job.progress) progress = std::make_unique<Progress>(job.label, total);
  io::PointBatch batch;
  std::vector<uint8_t> keep;
  uint64_t done = 0;
  for (size_t f = 0; f < job.inputs.size(); ++f) {
    if (!selection.may_keep(headers[f])) {
      ++result.files_skipped;
      done += headers[f].point_count;
      if (progress) progress->set(done);
      if (job.points_done) job.points_done->store(done);
      continue;
    }
    io::LasReader reader(job.inputs[f]);
    while (true) {
      batch.clear();
      const size_t n = reader.read(batch, job.batch_points);
      if (n == 0) break;
      result.points_read += n;
      done += n;
      if (selection.select(batch, keep) != n) batch.compact(keep);
      if (batch.size() > 0) sink(batch, selection, reader.header());
      if (progress) progress->set(done);
      if (job.points_done) job.points_done->store(done);
    }
  }
  if (progress) progress->finish();
}

}  // namespace stipple::pc::detail
