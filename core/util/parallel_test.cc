#include "core/util/parallel.h"

#include <atomic>
#include <stdexcept>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

namespace visloc {
namespace {

TEST(ParallelTest, RangesCoverEveryIndexOnceForAnyThreadCount) {
  for (int threads : {1, 2, 3, 7, 50}) {
    std::vector<int> visits(23, 0);
    std::atomic<int> calls{0};
    ParallelRanges(23, threads, [&](int begin, int end) {
      ++calls;
      EXPECT_LT(begin, end);  // No empty range.
      for (int i = begin; i < end; ++i) ++visits[i];
    });
    EXPECT_EQ(calls, std::min(threads, 23)) << threads << " threads";
    for (int v : visits) EXPECT_EQ(v, 1) << threads << " threads";
  }
  ParallelRanges(0, 2, [](int, int) { FAIL() << "no range for no work"; });
}

TEST(ParallelTest, RangesRunOnSeveralThreadsAndRethrow) {
  std::vector<std::thread::id> ids(2);
  ParallelRanges(2, 2, [&](int begin, int) { ids[begin] = std::this_thread::get_id(); });
  EXPECT_EQ(ids[0], std::this_thread::get_id());  // The first range runs on the caller.
  EXPECT_NE(ids[1], ids[0]);
  EXPECT_THROW(ParallelRanges(4, 2,
                              [](int begin, int) {
                                if (begin > 0) throw std::runtime_error("range failed");
                              }),
               std::runtime_error);
}

TEST(ParallelTest, RunBothRunsBothAndResolvesThreads) {
  for (int threads : {1, 2}) {
    bool first = false, second = false;
    RunBoth(threads, [&] { first = true; }, [&] { second = true; });
    EXPECT_TRUE(first && second);
  }
  EXPECT_EQ(ResolveThreads(3), 3);
  EXPECT_GE(ResolveThreads(0), 1);
}

}  // namespace
}  // namespace visloc
