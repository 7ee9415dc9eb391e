#include "core/util/cpu_placement.h"

#include <atomic>
#include <chrono>
#include <thread>

#include <gtest/gtest.h>

namespace visloc {
namespace {

// A thread that spins, saying where it runs, until told to stop.
struct SpinningThread {
  std::atomic<int64_t> id{0};
  std::atomic<int> cpu{-1};
  std::atomic<bool> stop{false};
  std::thread thread{[this] {
    id = CurrentThreadId();
    while (!stop) cpu = CurrentCpu();
  }};
  ~SpinningThread() {
    stop = true;
    thread.join();
  }
  // Waits (bounded) until the thread reports a core that `wanted` accepts; the last core seen.
  template <typename Wanted>
  int WaitForCpu(const Wanted& wanted) {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
    while (!wanted(cpu.load()) && std::chrono::steady_clock::now() < deadline) {
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    return cpu.load();
  }
};

TEST(CpuPlacementTest, ThisThreadIsOnOneOfItsOwnCores) {
  const CpuSet own = CpuSet::OfThisThread();
  ASSERT_GE(own.count(), 1);
  EXPECT_TRUE(own.contains(CurrentCpu()));
  EXPECT_GT(CurrentThreadId(), 0);
  EXPECT_FALSE(own.Without(CurrentCpu()).contains(CurrentCpu()));
  EXPECT_EQ(own.Without(CurrentCpu()).count(), own.count() - 1);
}

TEST(CpuPlacementTest, AThreadKeptOffItsCoreRunsOnAnotherAndCanTakeItsCoresBack) {
  const CpuSet own = CpuSet::OfThisThread();
  if (own.count() < 2) GTEST_SKIP() << "one core: nowhere else to go";
  SpinningThread spinner;
  const int from = spinner.WaitForCpu([&](int cpu) { return own.contains(cpu); });
  ASSERT_TRUE(own.contains(from));
  ASSERT_TRUE(KeepThreadOffCpu(spinner.id, own, from));
  EXPECT_NE(spinner.WaitForCpu([&](int cpu) { return cpu != from; }), from);
  // Its own cores again: it may run on `from` (pinned there, it does).
  ASSERT_TRUE(own.ApplyTo(spinner.id));
  ASSERT_TRUE(CpuSet::Single(from).ApplyTo(spinner.id));
  EXPECT_EQ(spinner.WaitForCpu([&](int cpu) { return cpu == from; }), from);
  EXPECT_TRUE(own.ApplyTo(spinner.id));
}

TEST(CpuPlacementTest, NoMoveThatWouldLeaveNoCoreOrNamesNoThread) {
  const int cpu = CurrentCpu();
  const CpuSet one = CpuSet::Single(cpu);
  EXPECT_EQ(one.count(), 1);
  EXPECT_FALSE(KeepThreadOffCpu(CurrentThreadId(), one, cpu));     // No core would be left.
  EXPECT_FALSE(KeepThreadOffCpu(0, CpuSet::OfThisThread(), cpu));  // 0 is no thread's id.
  EXPECT_FALSE(CpuSet::Single(-1).ApplyTo());                      // An empty set is refused.
  EXPECT_TRUE(CpuSet::OfThisThread().contains(CurrentCpu()));      // Nothing changed.
}

}  // namespace
}  // namespace visloc
