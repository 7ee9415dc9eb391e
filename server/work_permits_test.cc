#include <gtest/gtest.h>

#include <atomic>
#include <thread>
#include <vector>

#include "server/work_permits.h"

namespace visloc::server {
namespace {

// Eight "sessions" hammer two permits: never more than two hold one at a time, and every
// session gets its turns (no lost wake-up).
TEST(WorkPermitsTest, NeverMoreHoldersThanPermitsAndEveryoneGetsATurn) {
  WorkPermits permits(2);
  std::atomic<int> holding{0}, most{0}, turns{0};
  std::vector<std::thread> sessions;
  for (int s = 0; s < 8; ++s) {
    sessions.emplace_back([&] {
      for (int i = 0; i < 200; ++i) {
        permits.Acquire();
        const int now = ++holding;
        int seen = most.load();
        while (now > seen && !most.compare_exchange_weak(seen, now)) {
        }
        ++turns;
        --holding;
        permits.Release();
      }
    });
  }
  for (std::thread& t : sessions) t.join();
  EXPECT_LE(most.load(), 2);
  EXPECT_EQ(turns.load(), 8 * 200);
}

}  // namespace
}  // namespace visloc::server
