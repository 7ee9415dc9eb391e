#include "core/util/thread_priority.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <thread>

namespace visloc {
namespace {

TEST(ThreadPriorityTest, LowersTheCallingThreadOnly) {
  const int before = ThisThreadsNice();
  int in_thread_before = 0, in_thread_after = 0;
  std::thread lowered([&] {
    in_thread_before = ThisThreadsNice();
    in_thread_after = LowerThisThreadsPriority(5);
  });
  lowered.join();
  EXPECT_EQ(in_thread_before, before);  // A new thread starts at its creator's nice.
  EXPECT_EQ(in_thread_after, std::min(19, before + 5));
  EXPECT_EQ(ThisThreadsNice(), before);  // The caller's thread (and the process) unchanged.
}

TEST(ThreadPriorityTest, StopsAtTheLowestPriority) {
  int nice = 0;
  std::thread lowered([&] {
    LowerThisThreadsPriority(15);
    nice = LowerThisThreadsPriority(15);
  });
  lowered.join();
  EXPECT_EQ(nice, 19);
}

}  // namespace
}  // namespace visloc
