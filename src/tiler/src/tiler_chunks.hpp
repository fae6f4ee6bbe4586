#pragma once
// Chunk phase: the budget's shares (read batches, count grid, chunk size, in memory or out of
// core), the chunks cut from the count grid (the largest octree nodes of at most
// Build::chunk_points counted points, down to the part level in a split tiling), which chunks
// stay resident, the distribution of the records to the chunks (in memory: a parallel scatter
// into one array; out of core: resident ranges, or buffered appends to one temporary file a
// chunk), and the split of chunks that came out over budget. Each chunk is then indexed on its
// own (tiler_index).
#include <atomic>
#include <cstdint>
#include <filesystem>
#include <vector>

#include "tiler_build.hpp"

namespace stipple::tiler::detail {

// The shares of the budget for `threads` workers: batch_points, count_level, chunk_points,
// in_memory (and the staging array). Throws for parts finer than the count grid.
void plan_budget(Build& b, unsigned threads);

// Split tiling: drops the records outside the part (in place); returns how many are kept.
size_t keep_in_part(const Build& b, TilePoint* recs, size_t n);

// From the counted cells (freed here): the part's point total, b.chunks and b.cell_chunk, and
// out of core the resident chunks and the chunk buffers' size.
void plan_chunks(Build& b, std::vector<std::atomic<uint32_t>>& counts);

// Sorts a block of records by chunk and hands each run to its chunk (resident range or file).
void append_to_chunks(Build& b, const TilePoint* recs, size_t n);
// After a distribution pass: what the chunk buffers still hold goes to the files.
void flush_chunk_buffers(Build& b);
// Out of core, LAZ: the distribution pass over the staged records of `staged`.
void distribute(Build& b, const std::filesystem::path& staged, uint64_t count);
// In memory: the staged records scattered into b.resident, every chunk resident.
void distribute_in_memory(Build& b, uint64_t count);

// Every chunk's count from the distribution; throws unless they add up to the points counted.
void check_distribution(Build& b);
// A chunk over budget (a very dense fine cell) is split into its 8 children by streaming.
void split_oversized_chunks(Build& b);

}  // namespace stipple::tiler::detail
