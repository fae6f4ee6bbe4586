#include "stipple/renderer/suballocator.hpp"

#include <algorithm>
#include <atomic>
#include <bit>

#include "stipple/core/error.hpp"
#include "stipple/renderer/gpu.hpp"

namespace stipple::gpu {
namespace {

uint64_t align_up(uint64_t value, uint64_t alignment) {
  return (value + alignment - 1) & ~(alignment - 1);
}

}  // namespace

// ---- RangeAllocator ------------------------------------------------------------------------

RangeAllocator::RangeAllocator(uint64_t capacity)
    : capacity_(capacity), free_bytes_(capacity), largest_(capacity) {
  if (capacity > 0) free_.push_back({0, capacity});
}

void RangeAllocator::recompute_largest() {
  largest_ = 0;
  for (const FreeRange& r : free_) largest_ = std::max(largest_, r.size);
}

uint64_t RangeAllocator::allocate(uint64_t size, uint64_t alignment) {
  if (size == 0) fail("range allocator: zero-sized allocation");
  if (!std::has_single_bit(alignment))
    fail("range allocator: alignment {} is not a power of two", alignment);
  if (size > largest_) return npos;
  // First fit by address: keeps live ranges packed towards the start of the page.
  for (size_t i = 0; i < free_.size(); ++i) {
    FreeRange r = free_[i];
    uint64_t pad = align_up(r.offset, alignment) - r.offset;
    if (pad > r.size || size > r.size - pad) continue;
    uint64_t offset = r.offset + pad;
    uint64_t tail = r.size - pad - size;
    if (pad == 0 && tail == 0) {
      free_.erase(free_.begin() + ptrdiff_t(i));
    } else if (pad == 0) {
      free_[i] = {offset + size, tail};
    } else {
      free_[i].size = pad;
      if (tail) free_.insert(free_.begin() + ptrdiff_t(i) + 1, {offset + size, tail});
    }
    free_bytes_ -= size;
    // Only taking from the largest range can shrink the maximum.
    if (r.size == largest_) recompute_largest();
    return offset;
  }
  return npos;
}

void RangeAllocator::free(uint64_t offset, uint64_t size) {
  if (size == 0) fail("range allocator: freeing a zero-sized range at {}", offset);
  if (offset > capacity_ || size > capacity_ - offset)
    fail("range allocator: range [{}, +{}) lies outside the page of {} bytes", offset, size,
         capacity_);
  // Binary search: the first free range starting after `offset`.
  auto next = std::upper_bound(free_.begin(), free_.end(), offset,
                               [](uint64_t o, const FreeRange& r) { return o < r.offset; });
  bool has_prev = next != free_.begin();
  bool has_next = next != free_.end();
  auto prev = has_prev ? std::prev(next) : free_.end();
  if ((has_prev && prev->offset + prev->size > offset) ||
      (has_next && offset + size > next->offset))
    fail("range allocator: range [{}, +{}) overlaps free space (double free?)", offset, size);
  bool join_prev = has_prev && prev->offset + prev->size == offset;
  bool join_next = has_next && offset + size == next->offset;
  uint64_t merged;
  if (join_prev && join_next) {
    prev->size += size + next->size;
    merged = prev->size;
    free_.erase(next);
  } else if (join_prev) {
    merged = prev->size += size;
  } else if (join_next) {
    next->offset = offset;
    merged = next->size += size;
  } else {
    free_.insert(next, {offset, size});
    merged = size;
  }
  free_bytes_ += size;
  largest_ = std::max(largest_, merged);
}

// ---- Suballocator --------------------------------------------------------------------------

BufferSource device_buffer_source(Context& ctx) {
  BufferSource source;
  source.create = [&ctx](uint64_t size, WGPUBufferUsage usage, bool dedicated) {
    WGPUBufferDescriptor desc = WGPU_BUFFER_DESCRIPTOR_INIT;
    desc.label = to_view(dedicated ? "suballoc-dedicated" : "suballoc-page");
    desc.size = size;
    desc.usage = usage;
    return wgpuDeviceCreateBuffer(ctx.device.get(), &desc);
  };
  source.destroy = [](WGPUBuffer buffer) {
    // Destroy frees the memory now (once the GPU is done); release drops our reference.
    wgpuBufferDestroy(buffer);
    wgpuBufferRelease(buffer);
  };
  return source;
}

SuballocatorOptions suballocator_options(const Context& ctx, uint64_t page_size) {
  SuballocatorOptions options;
  options.page_size = page_size;
  options.storage_alignment = ctx.limits.minStorageBufferOffsetAlignment;
  options.uniform_alignment = ctx.limits.minUniformBufferOffsetAlignment;
  options.max_buffer_size = ctx.limits.maxBufferSize;
  return options;
}

Suballocator::Suballocator(Context& ctx, uint64_t page_size)
    : Suballocator(device_buffer_source(ctx), suballocator_options(ctx, page_size)) {}

Suballocator::Suballocator(BufferSource source, const SuballocatorOptions& options)
    : source_(std::move(source)), options_(options) {
  static std::atomic<uint32_t> next_id{1};
  id_ = next_id++;
  if (!source_.create || !source_.destroy) fail("suballocator: incomplete buffer source");
  if (options_.page_size == 0 || options_.page_size % 4 != 0)
    fail("suballocator: page size {} is not a positive multiple of 4", options_.page_size);
  if (options_.page_size > options_.max_buffer_size)
    fail("suballocator: page size {} exceeds the device's maxBufferSize ({})", options_.page_size,
         options_.max_buffer_size);
  for (uint64_t a : {options_.storage_alignment, options_.uniform_alignment})
    if (!std::has_single_bit(a)) fail("suballocator: alignment {} is not a power of two", a);
}

Suballocator::~Suballocator() {
  for (Pool& pool : pools_)
    for (WGPUBuffer buffer : pool.buffers)
      if (buffer) source_.destroy(buffer);
  for (const Slot& slot : slots_)
    if (slot.live && slot.page == kDedicated) source_.destroy(slot.buffer);
}

uint64_t Suballocator::alignment(WGPUBufferUsage usage) const {
  uint64_t a = 4;  // vertex/index offsets, copies, writeBuffer and indirect offsets
  if (usage & (WGPUBufferUsage_MapRead | WGPUBufferUsage_MapWrite)) a = std::max<uint64_t>(a, 8);
  if (usage & WGPUBufferUsage_Storage) a = std::max(a, options_.storage_alignment);
  if (usage & WGPUBufferUsage_Uniform) a = std::max(a, options_.uniform_alignment);
  if (usage & WGPUBufferUsage_QueryResolve) a = std::max<uint64_t>(a, 256);
  return a;
}

const Suballocator::Pool* Suballocator::find_pool(WGPUBufferUsage usage) const {
  for (const Pool& pool : pools_)
    if (pool.usage == usage) return &pool;
  return nullptr;
}

Suballocator::Pool& Suballocator::pool_for(WGPUBufferUsage usage) {
  for (Pool& pool : pools_)
    if (pool.usage == usage) return pool;
  Pool& pool = pools_.emplace_back();
  pool.usage = usage;
  pool.alignment = alignment(usage);
  return pool;
}

uint32_t Suballocator::new_page(Pool& pool) {
  WGPUBuffer buffer = source_.create(options_.page_size, pool.usage, false);
  if (!buffer) fail("suballocator: could not create a page of {} bytes", options_.page_size);
  // Reuse the index of a released page so that live slots keep their page numbers.
  auto vacant = std::find(pool.buffers.begin(), pool.buffers.end(), nullptr);
  uint32_t page = uint32_t(vacant - pool.buffers.begin());
  if (vacant == pool.buffers.end()) {
    pool.buffers.push_back(buffer);
    pool.ranges.emplace_back(options_.page_size);
    pool.largest.push_back(options_.page_size);
    pool.live.push_back(0);
  } else {
    pool.buffers[page] = buffer;
    pool.ranges[page] = RangeAllocator(options_.page_size);
    pool.largest[page] = options_.page_size;
    pool.live[page] = 0;
  }
  return page;
}

SubAllocation Suballocator::finish(uint32_t pool, uint32_t page, WGPUBuffer buffer, uint64_t offset,
                                   uint64_t size, uint64_t reserved) {
  uint32_t index;
  if (!free_slots_.empty()) {
    index = free_slots_.back();
    free_slots_.pop_back();
  } else {
    index = uint32_t(slots_.size());
    slots_.emplace_back();
  }
  Slot& slot = slots_[index];
  slot.buffer = buffer;
  slot.offset = offset;
  slot.reserved = reserved;
  slot.pool = pool;
  slot.page = page;
  slot.live = true;
  pools_[pool].used += reserved;
  pools_[pool].allocations++;
  SubAllocation a;
  a.buffer = buffer;
  a.offset = offset;
  a.size = size;
  a.reserved = reserved;
  a.slot = index;
  a.generation = slot.generation;
  a.owner = id_;
  return a;
}

SubAllocation Suballocator::allocate(uint64_t size, WGPUBufferUsage usage) {
  if (size == 0) fail("suballocator: zero-sized allocation");
  Pool& pool = pool_for(usage);
  uint32_t pool_index = uint32_t(&pool - pools_.data());
  // Sizes are rounded to the alignment, so every free range starts aligned and a page whose
  // largest free range holds `reserved` always succeeds: no padding, one search at most.
  uint64_t reserved = align_up(size, pool.alignment);
  if (reserved < size) fail("suballocator: allocation of {} bytes is too large", size);
  if (reserved > options_.page_size) {
    if (reserved > options_.max_buffer_size)
      fail("suballocator: allocation of {} bytes exceeds the device's maxBufferSize ({})", size,
           options_.max_buffer_size);
    WGPUBuffer buffer = source_.create(reserved, usage, true);
    if (!buffer) fail("suballocator: could not create a dedicated buffer of {} bytes", reserved);
    pool.dedicated++;
    pool.dedicated_bytes += reserved;
    return finish(pool_index, kDedicated, buffer, 0, size, reserved);
  }
  uint32_t page = 0;
  const uint32_t page_count = uint32_t(pool.largest.size());
  while (page < page_count && pool.largest[page] < reserved) ++page;
  uint64_t offset = RangeAllocator::npos;
  if (page < page_count) {
    ++page_searches_;
    offset = pool.ranges[page].allocate(reserved, pool.alignment);
  }
  if (offset == RangeAllocator::npos) {
    page = new_page(pool);
    ++page_searches_;
    offset = pool.ranges[page].allocate(reserved, pool.alignment);
  }
  pool.largest[page] = pool.ranges[page].largest_free();
  pool.live[page]++;
  return finish(pool_index, page, pool.buffers[page], offset, size, reserved);
}

void Suballocator::free(const SubAllocation& a) {
  if (a.owner != id_ || a.slot >= slots_.size())
    fail("suballocator: freeing an allocation that belongs to another suballocator (or none)");
  Slot& slot = slots_[a.slot];
  if (!slot.live || slot.generation != a.generation)
    fail("suballocator: double free of an allocation (offset {}, {} bytes)", a.offset, a.size);
  if (slot.buffer != a.buffer || slot.offset != a.offset || slot.reserved != a.reserved)
    fail("suballocator: freeing a modified allocation handle (offset {}, {} bytes)", a.offset,
         a.size);
  Pool& pool = pools_[slot.pool];
  if (slot.page == kDedicated) {
    source_.destroy(slot.buffer);
    pool.dedicated--;
    pool.dedicated_bytes -= slot.reserved;
  } else {
    pool.ranges[slot.page].free(slot.offset, slot.reserved);
    pool.largest[slot.page] = pool.ranges[slot.page].largest_free();
    pool.live[slot.page]--;
  }
  pool.used -= slot.reserved;
  pool.allocations--;
  slot.live = false;
  slot.buffer = nullptr;
  slot.generation++;
  free_slots_.push_back(a.slot);
}

uint32_t Suballocator::release_empty_pages() {
  uint32_t released = 0;
  for (Pool& pool : pools_)
    for (size_t page = 0; page < pool.buffers.size(); ++page) {
      if (!pool.buffers[page] || pool.live[page] > 0) continue;
      source_.destroy(pool.buffers[page]);
      pool.buffers[page] = nullptr;
      pool.ranges[page] = RangeAllocator();
      pool.largest[page] = 0;
      ++released;
    }
  return released;
}

void Suballocator::add_stats(const Pool& pool, SuballocatorStats& s) const {
  for (size_t page = 0; page < pool.buffers.size(); ++page) {
    if (!pool.buffers[page]) continue;
    s.pages++;
    s.bytes_reserved += pool.ranges[page].capacity();
    s.free_bytes += pool.ranges[page].free_bytes();
    s.largest_free = std::max(s.largest_free, pool.largest[page]);
  }
  s.dedicated_buffers += pool.dedicated;
  s.bytes_reserved += pool.dedicated_bytes;
  s.bytes_used += pool.used;
  s.allocations += pool.allocations;
}

SuballocatorStats Suballocator::stats() const {
  SuballocatorStats s;
  for (const Pool& pool : pools_) add_stats(pool, s);
  s.fragmentation = s.free_bytes ? 1.0 - double(s.largest_free) / double(s.free_bytes) : 0.0;
  s.page_searches = page_searches_;
  return s;
}

SuballocatorStats Suballocator::stats(WGPUBufferUsage usage) const {
  SuballocatorStats s;
  if (const Pool* pool = find_pool(usage)) add_stats(*pool, s);
  s.fragmentation = s.free_bytes ? 1.0 - double(s.largest_free) / double(s.free_bytes) : 0.0;
  s.page_searches = page_searches_;
  return s;
}

std::vector<PageInfo> Suballocator::pages(WGPUBufferUsage usage) const {
  std::vector<PageInfo> out;
  const Pool* pool = find_pool(usage);
  if (!pool) return out;
  for (size_t page = 0; page < pool->buffers.size(); ++page) {
    if (!pool->buffers[page]) continue;
    const RangeAllocator& r = pool->ranges[page];
    out.push_back({pool->buffers[page], r.capacity(), pool->largest[page], r.free_bytes(),
                   pool->live[page], r.free_ranges()});
  }
  return out;
}

}  // namespace stipple::gpu
