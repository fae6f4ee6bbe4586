// CPU tests of the buffer suballocator: the page free list against a reference model, and the
// pools over a fake buffer source (no device).
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <map>
#include <random>
#include <set>
#include <vector>

#include "stipple/core/error.hpp"
#include "stipple/renderer/suballocator.hpp"

using namespace stipple;
using gpu::FreeRange;
using gpu::RangeAllocator;

namespace {

// Reference model: live allocations by offset; the free space is everything between them.
using Live = std::map<uint64_t, uint64_t>;  // offset -> size

std::vector<FreeRange> gaps(const Live& live, uint64_t capacity) {
  std::vector<FreeRange> out;
  uint64_t cursor = 0;
  for (auto [offset, size] : live) {
    if (offset > cursor) out.push_back({cursor, offset - cursor});
    cursor = offset + size;
  }
  if (cursor < capacity) out.push_back({cursor, capacity - cursor});
  return out;
}

uint64_t align_up(uint64_t v, uint64_t a) {
  return (v + a - 1) / a * a;
}

// The first gap (by address) that holds `size` bytes at `alignment`, or npos.
uint64_t reference_first_fit(const std::vector<FreeRange>& free, uint64_t size,
                             uint64_t alignment) {
  for (const FreeRange& r : free) {
    uint64_t offset = align_up(r.offset, alignment);
    if (offset + size <= r.offset + r.size) return offset;
  }
  return RangeAllocator::npos;
}

// Everything the allocator reports must match the model exactly.
void check_against_model(const RangeAllocator& a, const Live& live) {
  std::vector<FreeRange> expected = gaps(live, a.capacity());
  std::vector<FreeRange> actual(a.free_ranges().begin(), a.free_ranges().end());
  // Equality with the maximal gaps means: sorted, no adjacent ranges left unmerged, nothing lost.
  ASSERT_EQ(actual, expected);
  uint64_t largest = 0, free_bytes = 0;
  for (const FreeRange& r : expected) {
    largest = std::max(largest, r.size);
    free_bytes += r.size;
  }
  ASSERT_EQ(a.largest_free(), largest);
  ASSERT_EQ(a.free_bytes(), free_bytes);
}

void random_sequence(uint64_t seed, uint64_t capacity, int ops) {
  SCOPED_TRACE("seed " + std::to_string(seed));
  std::mt19937_64 rng(seed);
  RangeAllocator a(capacity);
  Live live;
  const uint64_t alignments[] = {1, 4, 16, 256};
  int failures = 0;
  for (int op = 0; op < ops; ++op) {
    // Bias towards allocating while the page is emptyish, freeing when it is full.
    double fill = 1.0 - double(a.free_bytes()) / double(capacity);
    bool allocate = live.empty() || std::uniform_real_distribution<>(0, 1)(rng) > fill * 0.9;
    if (allocate) {
      // Mostly small sizes, some large ones (up to the whole page).
      uint64_t size = (rng() % 4 == 0) ? 1 + rng() % capacity : 1 + rng() % (capacity / 32);
      uint64_t alignment = alignments[rng() % 4];
      uint64_t expected = reference_first_fit(gaps(live, capacity), size, alignment);
      uint64_t offset = a.allocate(size, alignment);
      ASSERT_EQ(offset, expected) << "op " << op << " size " << size << " align " << alignment;
      if (offset == RangeAllocator::npos) {
        ++failures;
      } else {
        ASSERT_EQ(offset % alignment, 0u);
        ASSERT_LE(offset + size, capacity);
        // No overlap with the neighbours in the model.
        auto next = live.lower_bound(offset);
        if (next != live.end()) {
          ASSERT_LE(offset + size, next->first);
        }
        if (next != live.begin()) {
          ASSERT_LE(std::prev(next)->first + std::prev(next)->second, offset);
        }
        live[offset] = size;
      }
    } else {
      auto it = live.begin();
      std::advance(it, rng() % live.size());
      a.free(it->first, it->second);
      live.erase(it);
    }
    check_against_model(a, live);
  }
  EXPECT_GT(failures, 0) << "the sequence should also exercise full pages";
  // Free the rest in random order: one full range again.
  std::vector<std::pair<uint64_t, uint64_t>> rest(live.begin(), live.end());
  std::shuffle(rest.begin(), rest.end(), rng);
  for (auto [offset, size] : rest) {
    a.free(offset, size);
    live.erase(offset);
    check_against_model(a, live);
  }
  ASSERT_EQ(a.free_ranges().size(), 1u);
  EXPECT_EQ(a.free_ranges()[0], (FreeRange{0, capacity}));
  EXPECT_TRUE(a.all_free());
}

}  // namespace

TEST(RangeAllocator, RandomSequencesMatchReferenceModel) {
  for (uint64_t seed : {1, 2, 3, 42, 1234, 99991})
    random_sequence(seed, seed % 2 ? 1 << 16 : 100'000, 4000);
}

TEST(RangeAllocator, MergesWithBothNeighbours) {
  RangeAllocator a(300);
  ASSERT_EQ(a.allocate(100), 0u);
  ASSERT_EQ(a.allocate(100), 100u);
  ASSERT_EQ(a.allocate(100), 200u);
  EXPECT_EQ(a.largest_free(), 0u);
  EXPECT_EQ(a.allocate(1), RangeAllocator::npos);
  a.free(0, 100);
  a.free(200, 100);
  EXPECT_EQ(a.free_ranges().size(), 2u);
  EXPECT_EQ(a.largest_free(), 100u);
  a.free(100, 100);  // joins both sides
  ASSERT_EQ(a.free_ranges().size(), 1u);
  EXPECT_EQ(a.largest_free(), 300u);
}

TEST(RangeAllocator, AlignmentPaddingStaysFree) {
  RangeAllocator a(1024);
  ASSERT_EQ(a.allocate(10), 0u);
  ASSERT_EQ(a.allocate(16, 256), 256u);
  // [10, 256) is still free and usable.
  EXPECT_EQ(a.free_ranges()[0], (FreeRange{10, 246}));
  EXPECT_EQ(a.allocate(200, 2), 10u);
  EXPECT_EQ(a.free_bytes(), 1024u - 10 - 16 - 200);
}

TEST(RangeAllocator, EdgeCases) {
  RangeAllocator a(4096);
  EXPECT_THROW(a.allocate(0), Error);
  EXPECT_THROW(a.allocate(16, 3), Error);
  EXPECT_THROW(a.allocate(16, 0), Error);
  EXPECT_EQ(a.allocate(4097), RangeAllocator::npos);
  EXPECT_EQ(a.allocate(4096), 0u);  // size == page
  EXPECT_EQ(a.largest_free(), 0u);
  EXPECT_TRUE(a.free_ranges().empty());
  a.free(0, 4096);
  EXPECT_TRUE(a.all_free());
  // Double free, partial double free, out of range, zero size.
  uint64_t x = a.allocate(100);
  uint64_t y = a.allocate(100);
  a.free(x, 100);
  EXPECT_THROW(a.free(x, 100), Error);
  EXPECT_THROW(a.free(y + 50, 100), Error);  // overlaps the free tail
  EXPECT_THROW(a.free(4000, 200), Error);
  EXPECT_THROW(a.free(~uint64_t(0), 2), Error);
  EXPECT_THROW(a.free(y, 0), Error);
  // Failed frees change nothing.
  EXPECT_EQ(a.free_bytes(), 4096u - 100);
  a.free(y, 100);
  EXPECT_TRUE(a.all_free());
  EXPECT_EQ(RangeAllocator(0).allocate(1), RangeAllocator::npos);
}

// ---- pools over a fake buffer source ---------------------------------------------------------

namespace {

struct FakeDevice {
  uintptr_t next = 0x1000;
  std::map<WGPUBuffer, std::pair<uint64_t, bool>> alive;  // size, dedicated
  uint64_t created = 0, destroyed = 0;

  gpu::BufferSource source() {
    gpu::BufferSource s;
    s.create = [this](uint64_t size, WGPUBufferUsage, bool dedicated) {
      // Never dereferenced: only an identity.
      auto buffer = reinterpret_cast<WGPUBuffer>(next += 0x10);
      alive[buffer] = {size, dedicated};
      ++created;
      return buffer;
    };
    s.destroy = [this](WGPUBuffer buffer) {
      EXPECT_EQ(alive.erase(buffer), 1u) << "destroying an unknown buffer";
      ++destroyed;
    };
    return s;
  }
};

gpu::SuballocatorOptions small_pages(uint64_t page_size) {
  gpu::SuballocatorOptions o;
  o.page_size = page_size;
  o.storage_alignment = 256;
  o.uniform_alignment = 64;
  return o;
}

constexpr WGPUBufferUsage kVertex = WGPUBufferUsage_Vertex | WGPUBufferUsage_CopyDst;
constexpr WGPUBufferUsage kStorage = WGPUBufferUsage_Storage | WGPUBufferUsage_CopyDst;

}  // namespace

TEST(Suballocator, AlignmentFollowsUsage) {
  FakeDevice device;
  gpu::Suballocator sub(device.source(), small_pages(1 << 20));
  EXPECT_EQ(sub.alignment(kVertex), 4u);
  EXPECT_EQ(sub.alignment(WGPUBufferUsage_Index | WGPUBufferUsage_CopySrc), 4u);
  EXPECT_EQ(sub.alignment(WGPUBufferUsage_MapRead | WGPUBufferUsage_CopyDst), 8u);
  EXPECT_EQ(sub.alignment(kStorage), 256u);
  EXPECT_EQ(sub.alignment(WGPUBufferUsage_Uniform), 64u);
  EXPECT_EQ(sub.alignment(WGPUBufferUsage_QueryResolve), 256u);
}

TEST(Suballocator, RandomSequencesKeepPagesConsistent) {
  const uint64_t page = 1 << 20;
  for (uint64_t seed : {7, 8, 9, 2024}) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    std::mt19937_64 rng(seed);
    FakeDevice device;
    {
      gpu::Suballocator sub(device.source(), small_pages(page));
      std::vector<gpu::SubAllocation> live;
      for (int op = 0; op < 3000; ++op) {
        bool allocate = live.empty() || rng() % 100 < 55;
        if (allocate) {
          WGPUBufferUsage usage = rng() % 3 == 0 ? kStorage : kVertex;
          uint64_t size = rng() % 50 == 0 ? page + 1 + rng() % page : 1 + rng() % (page / 8);
          if (rng() % 40 == 0) size = page;
          uint64_t searches = sub.stats().page_searches;
          auto a = sub.allocate(size, usage);
          // One free-list search at most: pages whose largest range is too small are skipped.
          ASSERT_LE(sub.stats().page_searches - searches, 1u);
          ASSERT_TRUE(a);
          ASSERT_EQ(a.size, size);
          ASSERT_EQ(a.offset % sub.alignment(usage), 0u);
          ASSERT_GE(a.reserved, size);
          ASSERT_TRUE(device.alive.count(a.buffer));
          auto [buffer_size, dedicated] = device.alive[a.buffer];
          ASSERT_EQ(dedicated, size > page);
          ASSERT_LE(a.offset + a.reserved, buffer_size);
          live.push_back(a);
        } else {
          size_t i = rng() % live.size();
          sub.free(live[i]);
          live[i] = live.back();
          live.pop_back();
        }
        if (op % 50 != 0) continue;
        // Full check: no overlaps within a buffer; cached largest == true largest per page.
        std::map<WGPUBuffer, Live> by_buffer;
        for (const auto& a : live) {
          Live& l = by_buffer[a.buffer];
          auto next = l.lower_bound(a.offset);
          if (next != l.end()) {
            ASSERT_LE(a.offset + a.reserved, next->first);
          }
          if (next != l.begin()) {
            ASSERT_LE(std::prev(next)->first + std::prev(next)->second, a.offset);
          }
          l[a.offset] = a.reserved;
        }
        for (WGPUBufferUsage usage : {kVertex, kStorage})
          for (const auto& p : sub.pages(usage)) {
            auto g = gaps(by_buffer[p.buffer], p.size);
            uint64_t largest = 0;
            for (const auto& r : g) largest = std::max(largest, r.size);
            ASSERT_EQ(p.largest_free, largest);
            ASSERT_EQ(std::vector<FreeRange>(p.free_ranges.begin(), p.free_ranges.end()), g);
          }
        auto s = sub.stats();
        uint64_t used = 0;
        for (const auto& a : live) used += a.reserved;
        ASSERT_EQ(s.bytes_used, used);
        ASSERT_EQ(s.allocations, live.size());
        ASSERT_EQ(s.pages + s.dedicated_buffers, device.alive.size());
      }
      auto before = sub.stats();
      EXPECT_GT(before.pages, 1u);
      EXPECT_GT(before.dedicated_buffers, 0u);
      for (const auto& a : live) sub.free(a);
      // Everything coalesces back to one full range per page; dedicated buffers are gone.
      auto s = sub.stats();
      EXPECT_EQ(s.bytes_used, 0u);
      EXPECT_EQ(s.dedicated_buffers, 0u);
      EXPECT_EQ(s.fragmentation, s.pages > 1 ? 1.0 - 1.0 / s.pages : 0.0);
      for (WGPUBufferUsage usage : {kVertex, kStorage})
        for (const auto& p : sub.pages(usage)) {
          ASSERT_EQ(p.free_ranges.size(), 1u);
          EXPECT_EQ(p.largest_free, page);
          EXPECT_EQ(p.allocations, 0u);
        }
      EXPECT_EQ(sub.release_empty_pages(), s.pages);
      EXPECT_EQ(sub.stats().pages, 0u);
      EXPECT_TRUE(device.alive.empty());
      // Released page slots are reused.
      auto a = sub.allocate(100, kVertex);
      EXPECT_EQ(sub.stats().pages, 1u);
      sub.free(a);
    }
    EXPECT_TRUE(device.alive.empty()) << "the destructor releases every buffer";
    EXPECT_EQ(device.created, device.destroyed);
  }
}

TEST(Suballocator, FullPagesAreSkipped) {
  FakeDevice device;
  gpu::Suballocator sub(device.source(), small_pages(1 << 16));
  std::vector<gpu::SubAllocation> full;
  for (int i = 0; i < 8; ++i) full.push_back(sub.allocate(1 << 16, kVertex));  // size == page
  std::set<WGPUBuffer> buffers;
  for (const auto& a : full) {
    EXPECT_EQ(a.offset, 0u);
    buffers.insert(a.buffer);
  }
  EXPECT_EQ(buffers.size(), 8u);
  EXPECT_EQ(sub.stats().pages, 8u);
  uint64_t searches = sub.stats().page_searches;
  auto small = sub.allocate(64, kVertex);
  EXPECT_EQ(sub.stats().pages, 9u);  // a new page: the 8 full ones were not searched
  EXPECT_EQ(buffers.count(small.buffer), 0u);
  EXPECT_EQ(sub.stats().page_searches, searches + 1);
  // Room in page 5 is found without searching pages 0-4.
  sub.free(full[5]);
  searches = sub.stats().page_searches;
  auto again = sub.allocate(1 << 15, kVertex);
  EXPECT_EQ(again.buffer, full[5].buffer);
  EXPECT_EQ(sub.stats().page_searches, searches + 1);
  auto s = sub.stats();
  EXPECT_EQ(s.bytes_reserved, 9u << 16);
  EXPECT_EQ(s.bytes_used, (7u << 16) + (1u << 15) + 64);
  EXPECT_EQ(s.largest_free, (1u << 16) - 64);
  EXPECT_DOUBLE_EQ(s.fragmentation,
                   1.0 - double((1 << 16) - 64) / double((1 << 16) - 64 + (1 << 15)));
}

TEST(Suballocator, DedicatedBuffersAndPoolsPerUsage) {
  FakeDevice device;
  gpu::Suballocator sub(device.source(), small_pages(1 << 16));
  auto big = sub.allocate((1 << 16) + 1, kVertex);
  EXPECT_EQ(big.offset, 0u);
  EXPECT_EQ(device.alive[big.buffer], std::make_pair(uint64_t((1 << 16) + 4), true));
  auto s = sub.stats();
  EXPECT_EQ(s.pages, 0u);
  EXPECT_EQ(s.dedicated_buffers, 1u);
  EXPECT_EQ(s.bytes_reserved, (1u << 16) + 4);
  auto v = sub.allocate(10, kVertex);
  auto st = sub.allocate(10, kStorage);
  EXPECT_NE(v.buffer, st.buffer);  // separate pools
  EXPECT_EQ(sub.stats(kVertex).pages, 1u);
  EXPECT_EQ(sub.stats(kStorage).pages, 1u);
  EXPECT_EQ(sub.stats(kStorage).bytes_used, 256u);  // rounded to the storage alignment
  auto st2 = sub.allocate(10, kStorage);
  EXPECT_EQ(st2.offset, 256u);
  sub.free(big);
  EXPECT_EQ(sub.stats().dedicated_buffers, 0u);
  EXPECT_FALSE(device.alive.count(big.buffer));
}

TEST(Suballocator, BadFreesAreErrors) {
  FakeDevice device;
  gpu::Suballocator sub(device.source(), small_pages(1 << 16));
  gpu::Suballocator other(device.source(), small_pages(1 << 16));
  EXPECT_THROW(sub.allocate(0, kVertex), Error);
  auto a = sub.allocate(100, kVertex);
  auto b = other.allocate(100, kVertex);
  EXPECT_THROW(sub.free(b), Error);                     // foreign handle
  EXPECT_THROW(sub.free(gpu::SubAllocation{}), Error);  // empty handle
  auto tampered = a;
  tampered.offset += 4;
  EXPECT_THROW(sub.free(tampered), Error);
  sub.free(a);
  EXPECT_THROW(sub.free(a), Error);     // double free
  auto c = sub.allocate(100, kVertex);  // reuses a's slot with a new generation
  EXPECT_EQ(c.slot, a.slot);
  EXPECT_THROW(sub.free(a), Error);  // stale handle to a reused slot
  sub.free(c);
  other.free(b);
  EXPECT_EQ(sub.stats().bytes_used, 0u);
  // Invalid configuration.
  EXPECT_THROW(gpu::Suballocator(device.source(), small_pages(0)), Error);
  EXPECT_THROW(gpu::Suballocator(device.source(), small_pages(1001)), Error);
}
