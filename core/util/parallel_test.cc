#include "core/util/parallel.h"

#include <atomic>
#include <chrono>
#include <map>
#include <mutex>
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

TEST(ParallelTest, ChunksCoverEveryIndexOnceInRangesOfTheChunkForAnyThreadCount) {
  for (int threads : {1, 2, 3, 7}) {
    for (int chunk : {1, 4, 23, 100}) {
      std::vector<int> visits(23, 0);
      std::mutex mutex;
      std::vector<std::pair<int, int>> ranges;
      ParallelChunks(23, threads, chunk, [&](int begin, int end) {
        const std::lock_guard<std::mutex> lock(mutex);
        ranges.emplace_back(begin, end);
        for (int i = begin; i < end; ++i) ++visits[i];
      });
      for (int v : visits) EXPECT_EQ(v, 1) << threads << " threads, chunk " << chunk;
      for (const auto& [begin, end] : ranges) {
        EXPECT_EQ(begin % chunk, 0);
        EXPECT_EQ(end, std::min(23, begin + chunk));
      }
      EXPECT_EQ(ranges.size(), static_cast<size_t>((23 + chunk - 1) / chunk));
    }
  }
  ParallelChunks(0, 2, 4, [](int, int) { FAIL() << "no range for no work"; });
}

// A slow first half and a fast second: with two threads taking chunks as they finish, the thread
// that is not stuck in the slow chunk takes the rest, and both take part.
TEST(ParallelTest, ChunksKeepBothThreadsBusyAndRethrow) {
  std::mutex mutex;
  std::map<std::thread::id, int> chunks_by_thread;
  ParallelChunks(8, 2, 1, [&](int begin, int) {
    if (begin == 0) std::this_thread::sleep_for(std::chrono::milliseconds(50));
    const std::lock_guard<std::mutex> lock(mutex);
    ++chunks_by_thread[std::this_thread::get_id()];
  });
  ASSERT_EQ(chunks_by_thread.size(), 2u);
  int most = 0;
  for (const auto& [id, count] : chunks_by_thread) most = std::max(most, count);
  EXPECT_EQ(most, 7);  // The other thread took every chunk but the slow one.
  std::atomic<int> ran{0};
  EXPECT_THROW(ParallelChunks(6, 2, 2,
                              [&](int begin, int) {
                                ++ran;
                                if (begin == 2) throw std::runtime_error("chunk failed");
                              }),
               std::runtime_error);
  EXPECT_EQ(ran, 3);  // The other chunks still ran.
}

TEST(ParallelTest, RunBothRunsBothAndResolvesThreads) {
  for (int threads : {1, 2}) {
    bool first = false, second = false;
    RunBoth(
        threads, [&] { first = true; }, [&] { second = true; });
    EXPECT_TRUE(first && second);
  }
  EXPECT_EQ(ResolveThreads(3), 3);
  EXPECT_GE(ResolveThreads(0), 1);
}

}  // namespace
}  // namespace visloc
