#pragma once
// GPU buffer suballocator (seed 000, section 3.5): instead of one createBuffer per request, a pool
// per usage set hands out aligned ranges of large preallocated buffers ("pages").
//
// Two layers:
//  - RangeAllocator: the pure free-list logic of one page over [0, capacity), no GPU.
//  - Suballocator: pools of pages per WGPUBufferUsage; pages and dedicated buffers come from a
//    BufferSource (the device by default, a fake in unit tests).
// Neither is thread-safe: callers serialise access (the renderer owns one per device).
#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include <webgpu/webgpu.h>

namespace stipple::gpu {

struct Context;

struct FreeRange {
  uint64_t offset = 0;
  uint64_t size = 0;
  bool operator==(const FreeRange&) const = default;
};

// First-fit free list over [0, capacity). Free ranges are kept sorted by offset and never touch
// (a freed range merges with both neighbours), so the list is exactly the set of maximal gaps.
// Alignment padding in front of an allocation stays in the free list. Misuse (zero size, bad
// alignment, freeing a range that is outside the page or overlaps free space, i.e. a double
// free) throws stipple::Error.
class RangeAllocator {
 public:
  static constexpr uint64_t npos = ~uint64_t(0);

  explicit RangeAllocator(uint64_t capacity = 0);
  // Offset of a range of `size` bytes aligned to `alignment` (a power of two), or npos when no
  // free range can hold it.
  uint64_t allocate(uint64_t size, uint64_t alignment = 1);
  void free(uint64_t offset, uint64_t size);

  uint64_t capacity() const { return capacity_; }
  uint64_t free_bytes() const { return free_bytes_; }
  // Size of the largest free range, kept up to date so callers can skip full pages in O(1).
  uint64_t largest_free() const { return largest_; }
  bool all_free() const { return free_bytes_ == capacity_; }
  std::span<const FreeRange> free_ranges() const { return free_; }

 private:
  void recompute_largest();

  uint64_t capacity_ = 0;
  uint64_t free_bytes_ = 0;
  uint64_t largest_ = 0;
  std::vector<FreeRange> free_;
};

// A range of a pooled (or dedicated) buffer. The buffer is owned by the suballocator; the handle
// stays valid until it is freed or the suballocator is destroyed.
struct SubAllocation {
  WGPUBuffer buffer = nullptr;
  uint64_t offset = 0;
  uint64_t size = 0;      // as requested
  uint64_t reserved = 0;  // bytes held: size rounded up to the pool's alignment
  // Identify the allocation on free(): stale, double and foreign frees are caught.
  uint32_t slot = ~0u;
  uint32_t generation = 0;
  uint32_t owner = 0;
  explicit operator bool() const { return buffer != nullptr; }
};

// Where pages and dedicated buffers come from and go back to.
struct BufferSource {
  std::function<WGPUBuffer(uint64_t size, WGPUBufferUsage usage, bool dedicated)> create;
  std::function<void(WGPUBuffer buffer)> destroy;
};
// Real buffers on the context's device (destroy + release). The context must outlive the users.
BufferSource device_buffer_source(Context& ctx);

struct SuballocatorOptions {
  static constexpr uint64_t kDefaultPageSize = uint64_t(64) << 20;
  // The paper measures 16-128 MB; any multiple of 4 up to max_buffer_size is accepted.
  uint64_t page_size = kDefaultPageSize;
  uint64_t storage_alignment = 256;  // limits.minStorageBufferOffsetAlignment
  uint64_t uniform_alignment = 256;  // limits.minUniformBufferOffsetAlignment
  uint64_t max_buffer_size = ~uint64_t(0);
};
SuballocatorOptions suballocator_options(
    const Context& ctx, uint64_t page_size = SuballocatorOptions::kDefaultPageSize);

struct SuballocatorStats {
  uint32_t pages = 0;
  uint32_t dedicated_buffers = 0;
  uint64_t allocations = 0;     // live ones
  uint64_t bytes_reserved = 0;  // pages plus dedicated buffers
  uint64_t bytes_used = 0;      // reserved by live allocations (pages and dedicated)
  uint64_t free_bytes = 0;      // in pages
  uint64_t largest_free = 0;    // over all pages
  double fragmentation = 0.0;   // 1 - largest_free / free_bytes (0 when nothing is free)
  uint64_t page_searches = 0;   // page free lists searched so far (full pages are never searched)
};

struct PageInfo {
  WGPUBuffer buffer = nullptr;
  uint64_t size = 0;
  uint64_t largest_free = 0;  // the pool's cached value used to skip pages
  uint64_t free_bytes = 0;
  uint32_t allocations = 0;
  std::span<const FreeRange> free_ranges;
};

class Suballocator {
 public:
  Suballocator(Context& ctx, uint64_t page_size = SuballocatorOptions::kDefaultPageSize);
  Suballocator(BufferSource source, const SuballocatorOptions& options);
  Suballocator(const Suballocator&) = delete;
  Suballocator& operator=(const Suballocator&) = delete;
  // Destroys every page and dedicated buffer; outstanding handles become invalid.
  ~Suballocator();

  // A range of at least `size` bytes usable with `usage`, aligned for it. Requests larger than a
  // page get a dedicated buffer (offset 0). Throws stipple::Error for size 0, or when the
  // buffer source fails.
  SubAllocation allocate(uint64_t size, WGPUBufferUsage usage);
  // Throws stipple::Error for a handle that is not live in this suballocator.
  void free(const SubAllocation& allocation);
  // Gives pages without live allocations back to the buffer source; returns how many.
  uint32_t release_empty_pages();

  uint64_t page_size() const { return options_.page_size; }
  // Offset alignment for a usage set: 4 (vertex, index, copies, indirect), 8 with map usage,
  // the device's limits for storage and uniform, 256 for query resolve.
  uint64_t alignment(WGPUBufferUsage usage) const;
  SuballocatorStats stats() const;
  SuballocatorStats stats(WGPUBufferUsage usage) const;  // one pool (zeros when absent)
  std::vector<PageInfo> pages(WGPUBufferUsage usage) const;

 private:
  // Struct-of-arrays per pool: the page search only touches `largest`.
  struct Pool {
    WGPUBufferUsage usage = WGPUBufferUsage_None;
    uint64_t alignment = 4;
    std::vector<uint64_t> largest;  // per page; 0 for released pages, so they are skipped too
    std::vector<RangeAllocator> ranges;
    std::vector<WGPUBuffer> buffers;  // null for a released page (its index is reused)
    std::vector<uint32_t> live;       // live allocations per page
    uint32_t dedicated = 0;
    uint64_t dedicated_bytes = 0;
    uint64_t used = 0;
    uint64_t allocations = 0;
  };
  struct Slot {
    WGPUBuffer buffer = nullptr;
    uint64_t offset = 0, reserved = 0;
    uint32_t pool = 0, page = 0;  // page == kDedicated for a dedicated buffer
    uint32_t generation = 0;
    bool live = false;
  };
  static constexpr uint32_t kDedicated = ~0u;

  Pool& pool_for(WGPUBufferUsage usage);
  const Pool* find_pool(WGPUBufferUsage usage) const;
  uint32_t new_page(Pool& pool);
  SubAllocation finish(uint32_t pool, uint32_t page, WGPUBuffer buffer, uint64_t offset,
                       uint64_t size, uint64_t reserved);
  void add_stats(const Pool& pool, SuballocatorStats& stats) const;

  BufferSource source_;
  SuballocatorOptions options_;
  uint32_t id_ = 0;
  std::vector<Pool> pools_;  // a handful: linear lookup by usage
  std::vector<Slot> slots_;
  std::vector<uint32_t> free_slots_;
  uint64_t page_searches_ = 0;
};

}  // namespace stipple::gpu
