#pragma once
// Input phase: the LAS/LAZ headers (CRS, colour depth, precision, content attributes), the
// local ENU frame and the octree cube from the header boxes, and the passes over the points.
// A pass cuts every input into ranges of about Build::batch_points points (whole LAZ chunks for
// LAZ), decodes them on the pool and turns them into local positions or TilePoint records. The
// first pass counts the points of every cell of the count grid (and stages the records: in
// memory, or in a staging file when LAZ would cost decompressing twice); out of core on LAS
// only, a second pass reads the inputs again and hands the records to the chunks.
#include <atomic>
#include <cstdint>
#include <filesystem>
#include <vector>

#include "tiler_build.hpp"

namespace stipple::tiler::detail {

// Reads every input's header into b.inputs and b.total_points; checks the options against
// them and fills b.content. Throws stipple::Error for no inputs or no points.
void open_inputs(Build& b);

// b.frame (origin: mean ECEF of the inputs' box centres), the cube, root spacing, max level.
void make_frame_and_cube(Build& b);

// The reading pass: counts every point of the part in `counts` (cells of the count grid);
// stages the records in b.staged_mem (in memory) or in `staged` (unless `reread`: positions
// only, the records are made again by reread_and_distribute). Returns the points staged.
uint64_t read_and_count(Build& b, bool reread, std::vector<std::atomic<uint32_t>>& counts,
                        const std::filesystem::path& staged);

// Out of core on LAS: reads the inputs again and appends the part's records to the chunks.
void reread_and_distribute(Build& b);

}  // namespace stipple::tiler::detail
