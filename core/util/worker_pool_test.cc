#include "core/util/worker_pool.h"

#include <atomic>
#include <chrono>
#include <set>
#include <stdexcept>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

namespace visloc {
namespace {

TEST(WorkerPoolTest, RangesCoverEveryIndexOnceForAnyThreadCountAndJobAfterJob) {
  WorkerPool pool(3);
  for (int job = 0; job < 200; ++job) {
    for (int threads : {1, 2, 4, 9}) {
      std::vector<int> visits(7, 0);
      std::atomic<int> calls{0};
      pool.Ranges(7, threads, [&](int begin, int end) {
        ++calls;
        EXPECT_LT(begin, end);  // No empty range.
        for (int i = begin; i < end; ++i) ++visits[i];
      });
      EXPECT_EQ(calls, std::min(threads, 4)) << threads << " threads";  // 3 helpers + caller.
      for (int v : visits) ASSERT_EQ(v, 1) << threads << " threads, job " << job;
    }
  }
  pool.Ranges(0, 2, [](int, int) { FAIL() << "no range for no work"; });
}

TEST(WorkerPoolTest, HelpersAreTheSameThreadsFromJobToJobBesideTheCaller) {
  WorkerPool pool(1);
  std::set<std::thread::id> helper_ids;
  for (int job = 0; job < 20; ++job) {
    std::vector<std::thread::id> ids(2);
    pool.Ranges(2, 2, [&](int begin, int) { ids[begin] = std::this_thread::get_id(); });
    EXPECT_EQ(ids[0], std::this_thread::get_id());  // The first range runs on the caller.
    EXPECT_NE(ids[1], ids[0]);
    helper_ids.insert(ids[1]);
    // Jobs both while the helper still spins and after it has gone to sleep.
    if (job % 2) std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  EXPECT_EQ(helper_ids.size(), 1u);
}

TEST(WorkerPoolTest, RethrowsTheLowestRangesErrorAfterAllRanAndKeepsWorking) {
  WorkerPool pool(2);
  std::atomic<int> ran{0};
  try {
    pool.Ranges(3, 3, [&](int begin, int) {
      ++ran;
      if (begin > 0) throw std::runtime_error("range " + std::to_string(begin));
    });
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_STREQ(e.what(), "range 1");
  }
  EXPECT_EQ(ran, 3);
  std::atomic<int> after{0};
  pool.Ranges(3, 3, [&](int, int) { ++after; });
  EXPECT_EQ(after, 3);
}

TEST(WorkerPoolTest, APoolWithoutHelpersRunsOnTheCaller) {
  WorkerPool pool(0);
  std::vector<std::thread::id> ids;
  pool.Ranges(4, 4, [&](int begin, int end) {
    EXPECT_EQ(begin, 0);
    EXPECT_EQ(end, 4);
    ids.push_back(std::this_thread::get_id());
  });
  ASSERT_EQ(ids.size(), 1u);
  EXPECT_EQ(ids[0], std::this_thread::get_id());
}

}  // namespace
}  // namespace visloc
