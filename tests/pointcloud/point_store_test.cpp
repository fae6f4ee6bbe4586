// The compaction info of the virtual memory system (seed 002, III-C1) on the CPU: kept ranges
// come from where the previous frame had them, new points follow them, jobs cover the next
// buffers exactly, and a bounded transfer is shared among the pointlets.
#include <numeric>
#include <random>

#include <gtest/gtest.h>

#include "stipple/core/thread_pool.hpp"
#include "stipple/pointcloud/point_store.hpp"

using namespace stipple;

namespace {

// Replays the jobs over "point ids" (pointlet << 32 | index in pointlet): the next buffers must
// hold, for every pointlet in order, exactly the prefix the plan says it draws.
void expect_plan_builds_prefixes(const pc::StoreLayout& before, const pc::CompactionPlan& plan) {
  std::vector<uint64_t> previous(before.total);
  for (size_t i = 0; i < before.count.size(); ++i)
    for (uint32_t k = 0; k < before.count[i]; ++k)
      previous[before.first[i] + k] = (uint64_t(i) << 32) | k;
  std::vector<uint64_t> fresh(plan.fresh_points);
  for (const pc::FreshRange& r : plan.fresh)
    for (uint32_t k = 0; k < r.count; ++k)
      fresh[r.at + k] = (uint64_t(r.pointlet) << 32) | (r.first + k);
  std::vector<uint64_t> next(plan.next.total, ~uint64_t(0));
  uint64_t covered = 0;
  for (size_t j = 0; j < plan.jobs.size(); ++j) {
    const pc::CompactionJob& job = plan.jobs[j];
    ASSERT_EQ(job.dst, covered) << "job " << j;
    ASSERT_GT(job.count, 0u);
    for (uint32_t k = 0; k < job.count; ++k)
      next[job.dst + k] = job.fresh ? fresh.at(job.src + k) : previous.at(job.src + k);
    covered += job.count;
  }
  ASSERT_EQ(covered, plan.next.total);
  uint64_t at = 0;
  for (size_t i = 0; i < plan.next.count.size(); ++i) {
    if (plan.next.count[i] == 0) continue;
    ASSERT_EQ(plan.next.first[i], at);
    for (uint32_t k = 0; k < plan.next.count[i]; ++k)
      ASSERT_EQ(next[at + k], (uint64_t(i) << 32) | k) << "pointlet " << i << " point " << k;
    at += plan.next.count[i];
  }
}

}  // namespace

TEST(Compaction, KeepsThePreviousPrefixAndAppendsNewPoints) {
  pc::StoreLayout none;
  auto first = pc::plan_compaction(none, {3, 0, 5}, 100);
  EXPECT_EQ(first.kept, 0u);
  EXPECT_EQ(first.fresh_points, 8u);
  EXPECT_FALSE(first.limited);
  expect_plan_builds_prefixes(none, first);
  // Pointlet 0 shrinks to 1, 1 appears with 2, 2 grows to 7: 1 + 5 kept, 2 + 2 new.
  auto second = pc::plan_compaction(first.next, {1, 2, 7}, 100);
  EXPECT_EQ(second.kept, 6u);
  EXPECT_EQ(second.fresh_points, 4u);
  expect_plan_builds_prefixes(first.next, second);
  // Unchanged counts: one merged job copying everything, nothing new.
  auto same = pc::plan_compaction(second.next, second.next.count, 100);
  EXPECT_EQ(same.fresh_points, 0u);
  ASSERT_EQ(same.jobs.size(), 1u);
  EXPECT_EQ(same.jobs[0].count, 10u);
}

TEST(Compaction, RandomSequencesWithABoundedTransfer) {
  std::mt19937 rng(7);
  for (uint64_t max_fresh : {uint64_t(1) << 40, uint64_t(500), uint64_t(37)}) {
    SCOPED_TRACE(max_fresh);
    pc::StoreLayout layout;
    for (int step = 0; step < 60; ++step) {
      std::vector<uint32_t> wanted(300);
      for (auto& w : wanted) w = rng() % 4 == 0 ? 0 : rng() % 64;
      // Repeats of one request converge on it within ceil(lack / max_fresh) steps.
      for (int repeat = 0; repeat < 3 + step % 2; ++repeat) {
        auto plan = pc::plan_compaction(layout, wanted, max_fresh);
        expect_plan_builds_prefixes(layout, plan);
        if (HasFatalFailure()) return;
        EXPECT_LE(plan.fresh_points, max_fresh);
        uint64_t lack = 0;
        for (size_t i = 0; i < wanted.size(); ++i) {
          ASSERT_LE(plan.next.count[i], wanted[i]);
          const uint32_t before = layout.count.empty() ? 0 : layout.count[i];
          ASSERT_GE(plan.next.count[i], std::min(before, wanted[i]));  // nothing kept is lost
          lack += wanted[i] - plan.next.count[i];
        }
        EXPECT_EQ(plan.limited, lack > 0);
        if (plan.limited) {
          EXPECT_EQ(plan.fresh_points, max_fresh);  // the transfer is used fully
        }
        layout = plan.next;
      }
    }
  }
}

TEST(Compaction, RefusesAMismatchedPointletCount) {
  auto plan = pc::plan_compaction({}, {1, 2}, 10);
  EXPECT_THROW(pc::plan_compaction(plan.next, {1, 2, 3}, 10), std::exception);
}

// Planned on a pool, in pieces of pointlets: the same plan as on one thread (jobs, new ranges,
// layout), and still one that rebuilds every prefix, across pieces and with a bounded transfer.
TEST(Compaction, APoolPlansWhatOneThreadPlans) {
  ThreadPool pool(3);
  std::mt19937 rng(11);
  for (uint64_t max_fresh : {uint64_t(1) << 40, uint64_t(20'000)}) {
    SCOPED_TRACE(max_fresh);
    pc::StoreLayout layout;
    for (int step = 0; step < 6; ++step) {
      std::vector<uint32_t> wanted(30'011);  // four pieces, the last one short
      for (auto& w : wanted) w = rng() % 3 == 0 ? 0 : rng() % 9;
      if (step == 5) wanted = layout.count;  // unchanged: nothing to do
      const auto alone = pc::plan_compaction(layout, wanted, max_fresh);
      const auto pooled = pc::plan_compaction(layout, wanted, max_fresh, &pool);
      expect_plan_builds_prefixes(layout, pooled);
      if (HasFatalFailure()) return;
      ASSERT_EQ(pooled.jobs.size(), alone.jobs.size());
      for (size_t j = 0; j < alone.jobs.size(); ++j) {
        EXPECT_EQ(pooled.jobs[j].dst, alone.jobs[j].dst);
        EXPECT_EQ(pooled.jobs[j].src, alone.jobs[j].src);
        EXPECT_EQ(pooled.jobs[j].count, alone.jobs[j].count);
        EXPECT_EQ(pooled.jobs[j].fresh, alone.jobs[j].fresh);
      }
      ASSERT_EQ(pooled.fresh.size(), alone.fresh.size());
      EXPECT_EQ(pooled.next.first, alone.next.first);
      EXPECT_EQ(pooled.next.count, alone.next.count);
      EXPECT_EQ(pooled.fresh_points, alone.fresh_points);
      EXPECT_EQ(pooled.kept, alone.kept);
      EXPECT_EQ(pooled.limited, alone.limited);
      EXPECT_EQ(pooled.changed, step != 5);
      if (max_fresh < 100'000 && step == 0) {
        EXPECT_TRUE(pooled.limited);
      }
      layout = pooled.next;
    }
  }
}
