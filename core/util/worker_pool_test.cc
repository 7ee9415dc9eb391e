#include "core/util/worker_pool.h"

#include <atomic>
#include <chrono>
#include <mutex>
#include <set>
#include <stdexcept>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "core/util/cpu_placement.h"

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

TEST(WorkerPoolTest, ClaimedPartsRunOnceEachOnAtMostTheThreadsAskedFor) {
  WorkerPool pool(3);
  for (int job = 0; job < 100; ++job) {
    for (int threads : {1, 2, 4}) {
      std::vector<int> visits(6, 0);
      std::mutex mutex;
      std::set<std::thread::id> ran_on;
      pool.ForEachClaimed(6, threads, [&](int i) {
        ++visits[i];
        std::lock_guard<std::mutex> lock(mutex);
        ran_on.insert(std::this_thread::get_id());
      });
      for (int v : visits) ASSERT_EQ(v, 1) << threads << " threads, job " << job;
      ASSERT_LE(static_cast<int>(ran_on.size()), threads) << "job " << job;
    }
  }
}

TEST(WorkerPoolTest, WhileTheCallersPartRunsTheHelperTakesTheRest) {
  // Part 0 (the caller's camera) lasts until the others are done (bounded, should the helper
  // never come): the helper, once awake, claims parts 1, 2, 3 one after the other, so the parts
  // that do not wait for part 0 end beside it.
  WorkerPool pool(1);
  for (int job = 0; job < 10; ++job) {
    std::vector<std::thread::id> ids(4);
    std::atomic<int> others_done{0};
    pool.ForEachClaimed(4, 2, [&](int i) {
      ids[i] = std::this_thread::get_id();
      if (i > 0) {
        ++others_done;
        return;
      }
      const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
      while (others_done < 3 && std::chrono::steady_clock::now() < deadline) {
        std::this_thread::sleep_for(std::chrono::microseconds(100));
      }
    });
    EXPECT_EQ(ids[0], std::this_thread::get_id());
    for (int i = 1; i < 4; ++i) EXPECT_NE(ids[i], ids[0]) << "part " << i << ", job " << job;
  }
}

TEST(WorkerPoolTest, HelpersAreTheSameThreadsFromJobToJobBesideTheCaller) {
  WorkerPool pool(1);
  std::set<std::thread::id> helper_ids;
  int helper_ran = 0;
  for (int job = 0; job < 20; ++job) {
    std::vector<std::thread::id> ids(2);
    pool.Ranges(2, 2, [&](int begin, int) {
      ids[begin] = std::this_thread::get_id();
      // The caller's part lasts long enough for the helper to wake and claim the other.
      if (begin == 0) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    });
    EXPECT_EQ(ids[0], std::this_thread::get_id());  // The first range runs on the caller.
    if (ids[1] != ids[0]) {                         // Or the caller took it: the helper was late.
      helper_ids.insert(ids[1]);
      ++helper_ran;
    }
    // Jobs both while the helper still spins and after it has gone to sleep.
    if (job % 2) std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  EXPECT_GT(helper_ran, 0);
  EXPECT_EQ(helper_ids.size(), 1u);
}

TEST(WorkerPoolTest, APartNoHelperHasStartedRunsOnTheCallerAndALateHelperRunsNothingStale) {
  // The helper wakes 100 ms late for every job (its core busy elsewhere): the caller runs every
  // part itself and returns; the helper, waking during job k + 2 with job k's body, must not run
  // it for the job in progress.
  WorkerPool pool(1);
  pool.set_helper_delay_for_test(std::chrono::milliseconds(100));
  for (int job = 0; job < 5; ++job) {
    std::vector<std::thread::id> ids(2);
    std::vector<int> visits(6, 0);
    pool.Ranges(6, 2, [&](int begin, int end) {
      ids[begin == 0 ? 0 : 1] = std::this_thread::get_id();
      for (int i = begin; i < end; ++i) ++visits[i];
      // Long enough for the helper to take up the job's body and start its delay, so that it
      // wakes during a later job holding this one's.
      if (begin == 0) std::this_thread::sleep_for(std::chrono::milliseconds(40));
    });
    EXPECT_EQ(ids[0], std::this_thread::get_id());
    EXPECT_EQ(ids[1], std::this_thread::get_id()) << "job " << job;
    for (int v : visits) EXPECT_EQ(v, 1) << "job " << job;
  }
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

namespace visloc {
namespace {

// Polls `done` for up to 10 s (the helpers run on a shared machine); whether it became true.
template <typename Done>
bool Eventually(const Done& done) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  while (!done()) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return true;
}

TEST(WorkerPoolTest, AHelperWakesForAnExpectedJobAndMeetsIt) {
  WorkerPool pool(1);
  std::atomic<int> runs{0};
  pool.ForEachClaimed(2, 2, [&](int) { ++runs; });  // Starts the helper.
  // Asleep once its spin after that job ends; the expectation wakes it 5 ms before the job is
  // due, and it looks for the job for up to 10 s after.
  using std::chrono::milliseconds;
  pool.ExpectJob(std::chrono::steady_clock::now() + milliseconds(20), milliseconds(5),
                 std::chrono::seconds(10));
  ASSERT_TRUE(Eventually([&] { return pool.expectation_stats().wakes == 1; }));
  std::this_thread::sleep_for(milliseconds(30));
  pool.ForEachClaimed(2, 2, [&](int) { ++runs; });
  EXPECT_EQ(runs, 4);
  ASSERT_TRUE(Eventually([&] { return pool.expectation_stats().met == 1; }));
  EXPECT_EQ(pool.expectation_stats().missed, 0);
  EXPECT_EQ(pool.expectation_stats().wakes, 1);
}

TEST(WorkerPoolTest, AnExpectedJobThatDoesNotComeLetsTheHelperSleepAgain) {
  WorkerPool pool(2);
  pool.ForEachClaimed(3, 3, [](int) {});
  using std::chrono::milliseconds;
  pool.ExpectJob(std::chrono::steady_clock::now() + milliseconds(2), milliseconds(1),
                 milliseconds(3));
  // Both helpers wake for it, look for 4 ms, and go back to sleep: each counts a miss.
  ASSERT_TRUE(Eventually([&] { return pool.expectation_stats().missed == 2; }));
  const WorkerPool::ExpectationStats stats = pool.expectation_stats();
  EXPECT_EQ(stats.wakes, 2);
  EXPECT_EQ(stats.met, 0);
  // Asleep, they still take the next job.
  std::atomic<int> runs{0};
  pool.ForEachClaimed(3, 3, [&](int) { ++runs; });
  EXPECT_EQ(runs, 3);
  EXPECT_EQ(pool.expectation_stats().wakes, 2);  // No expectation left to wake for.
}

TEST(WorkerPoolTest, AHelperOnTheCallersCoreIsMovedToAnotherAndRunsItsPartThere) {
  // The scheduler can leave a helper waiting to run on the caller's core while another core
  // idles; the caller then runs every part itself. Here the helper is pinned to the caller's
  // core as the scheduler could leave it, and the caller's part computes until the helper's
  // is done (bounded): the caller must move the helper for it to run beside.
  const CpuSet own = CpuSet::OfThisThread();
  if (own.count() < 2) GTEST_SKIP() << "one core: nowhere to move the helper";
  // The helper starts with this thread's cores (a thread inherits its creator's), all of them.
  WorkerPool pool(1);
  pool.ForEachClaimed(2, 2, [](int) {});
  const int caller_cpu = CurrentCpu();
  ASSERT_TRUE(CpuSet::Single(caller_cpu).ApplyTo());
  struct Restore {
    const CpuSet& own;
    ~Restore() { own.ApplyTo(); }
  } restore{own};
  ASSERT_TRUE(pool.PinHelperForTest(0, caller_cpu));
  std::atomic<bool> helper_part_done{false};
  std::atomic<int> helper_part_cpu{-1};
  std::thread::id helper_part_thread;
  const auto started = std::chrono::steady_clock::now();
  pool.ForEachClaimed(2, 2, [&](int i) {
    if (i == 1) {
      helper_part_cpu = CurrentCpu();
      helper_part_thread = std::this_thread::get_id();
      helper_part_done = true;
      return;
    }
    while (!helper_part_done &&
           std::chrono::steady_clock::now() - started < std::chrono::seconds(2)) {
    }
  });
  EXPECT_NE(helper_part_thread, std::this_thread::get_id());
  EXPECT_NE(helper_part_cpu, caller_cpu);
  // At least this move (the start may have made one too, and a helper moved just after it took
  // that job takes back its cores only with the next: the pin may be undone, no move needed).
  EXPECT_GE(pool.helpers_moved(), 1);
  // Moved, the helper took back its own cores: a later job runs as any other.
  std::atomic<int> parts{0};
  pool.ForEachClaimed(4, 2, [&](int) { ++parts; });
  EXPECT_EQ(parts, 4);
}

}  // namespace
}  // namespace visloc
