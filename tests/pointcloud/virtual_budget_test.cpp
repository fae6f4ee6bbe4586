// The points' share of a process budget (the virtualized path's --host-memory): what the rest
// of the process holds and a margin are left out, and host_budget stays the cap.
#include <gtest/gtest.h>

#include <algorithm>

#include "stipple/pointcloud/virtual_cloud.hpp"

using namespace stipple;

TEST(VirtualBudget, PointsGetWhatTheProcessLeaves) {
  constexpr uint64_t MiB = uint64_t(1) << 20;
  // 4 GiB for a process holding 900 MiB, 100 of them points: 800 MiB and a 5% margin are out.
  EXPECT_EQ(pc::points_budget(4096 * MiB, 900 * MiB, 100 * MiB, 8192 * MiB),
            4096 * MiB - 800 * MiB - 4096 * MiB / 20);
  // The cap stays the cap.
  EXPECT_EQ(pc::points_budget(4096 * MiB, 900 * MiB, 100 * MiB, 1000 * MiB), 1000 * MiB);
  // Small budgets keep a 32 MiB margin; a process over its budget leaves nothing.
  EXPECT_EQ(pc::points_budget(200 * MiB, 100 * MiB, 0, 1000 * MiB), 68 * MiB);
  EXPECT_EQ(pc::points_budget(200 * MiB, 190 * MiB, 0, 1000 * MiB), 0u);
  // Loaded points are not counted as the process's own (resident below loaded: none).
  EXPECT_EQ(pc::points_budget(200 * MiB, 10 * MiB, 50 * MiB, 1000 * MiB), 168 * MiB);
}

// The least process budget that leaves what is needed after points_budget's margin.
TEST(VirtualBudget, MinimumLeavesTheNeedAfterTheMargin) {
  constexpr uint64_t MiB = uint64_t(1) << 20;
  for (const uint64_t need : {10 * MiB, 300 * MiB, 900 * MiB, 5000 * MiB}) {
    SCOPED_TRACE(need);
    const uint64_t minimum = pc::minimum_process_budget(need);
    // At the minimum the rest of the process (need) and the margin fit; a MiB less, not.
    EXPECT_GE(minimum - std::max(32 * MiB, minimum / 20), need);
    const uint64_t less = minimum - MiB;
    EXPECT_LT(less - std::min(less, std::max(32 * MiB, less / 20)), need);
  }
}
