// The process's resident memory: it is measured, it grows by what is touched, and the peak is
// at least the current value.
#include <cstring>
#include <vector>

#include <gtest/gtest.h>

#include "stipple/core/memory.hpp"

using namespace stipple;

TEST(Memory, ResidentBytesFollowTouchedMemory) {
  const uint64_t before = resident_bytes();
  ASSERT_GT(before, 0u);
  std::vector<char> block(64 << 20);
  std::memset(block.data(), 1, block.size());  // resident only once touched
  const uint64_t after = resident_bytes();
  EXPECT_GE(after, before + (48u << 20));
  // The kernel updates the high-water mark lazily: within 4 MiB of the current value.
  EXPECT_GE(peak_resident_bytes() + (4u << 20), after);
  EXPECT_EQ(block[12345], 1);
}
