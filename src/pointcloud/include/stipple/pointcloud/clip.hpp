#pragma once
// Export of the points a filter and clip region keep, from LAS/LAZ/COPC inputs to one LAS or LAZ
// file: `stipple clip` and the viewer's export run this. It streams (memory bounded by a batch,
// whatever the input size), keeps every field of each record (extra bytes included), the first
// input's VLRs, EVLRs and CRS, and writes a LAS 1.4 header whose counts by return and bounds are
// those of what was written; the output appears only when complete.
#include <atomic>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <vector>

#include <glm/vec3.hpp>

#include "stipple/io/las.hpp"
#include "stipple/pointcloud/filters.hpp"

namespace stipple::pc {

struct ClipJob {
  std::vector<std::filesystem::path> inputs;
  std::filesystem::path output;  // .laz compresses
  PointFilter filter;
  ClipRegion region;  // Highlight is taken as Inside
  // Lon/lat inputs: the region is in the local east-north-up frame at this origin (lon, lat, h),
  // as the renderer draws them; unset: in the source coordinates.
  std::optional<glm::dvec3> enu_origin;
  bool progress = true;  // a progress bar on stderr
  // Points read so far, for a caller watching from another thread (the viewer).
  std::atomic<uint64_t>* points_done = nullptr;
  size_t batch_points = 1 << 16;
};

struct ClipResult {
  uint64_t points_read = 0;
  uint64_t points_written = 0;
  uint64_t files_skipped = 0;  // inputs whose header bounds lie outside the region
  uint8_t point_format = 0;
  glm::dvec3 min{0.0}, max{0.0};
};

// Throws stipple::Error naming the file and the problem; nothing is left at `output` then.
ClipResult clip_to_las(const ClipJob& job);

// The layout of a file that takes points from these inputs: the first input's point format,
// scale, offset, VLRs, EVLRs and CRS when every input agrees on them, else a LAS 1.4 format that
// holds every input's attributes at the finest scale. Throws when the inputs' CRSs or extra
// bytes differ. `output`'s extension (.laz) chooses compression.
io::LasWriteOptions clip_output_options(const std::vector<io::LasHeader>& headers,
                                        const std::filesystem::path& output);

// The points of the inputs a job would keep, counted without writing (same tests as
// clip_to_las), e.g. for a reference count.
uint64_t count_kept_points(const ClipJob& job);

}  // namespace stipple::pc
