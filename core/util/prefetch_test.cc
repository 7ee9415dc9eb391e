#include "core/util/prefetch.h"

#include <atomic>
#include <chrono>
#include <memory>
#include <stdexcept>
#include <string>
#include <thread>

#include <gtest/gtest.h>

namespace visloc {
namespace {

TEST(OrderedPrefetchTest, ItemsComeInOrderEachMadeOnce) {
  for (int depth : {1, 3, 50}) {
    std::atomic<int> made{0};
    OrderedPrefetch<std::unique_ptr<int>> items(20, depth, [&](int i) {
      ++made;
      return std::make_unique<int>(i * i);  // Move-only items too.
    });
    for (int i = 0; i < 20; ++i) EXPECT_EQ(*items.Next(), i * i) << "depth " << depth;
    EXPECT_EQ(made, 20);
  }
}

TEST(OrderedPrefetchTest, NoMoreThanDepthItemsAreMadeAhead) {
  std::atomic<int> made{0};
  OrderedPrefetch<int> items(100, 4, [&](int i) { return ++made, i; });
  EXPECT_EQ(items.Next(), 0);
  // The maker stops when 4 wait untaken: at most 1 taken + 4 waiting.
  for (int spin = 0; spin < 200 && made < 5; ++spin) std::this_thread::yield();
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  EXPECT_LE(made, 5);
  EXPECT_EQ(items.Next(), 1);
}

TEST(OrderedPrefetchTest, AFailureReachesTheCallerAtItsItemAndNothingAfterIsMade) {
  std::atomic<int> made{0};
  OrderedPrefetch<int> items(10, 5, [&](int i) {
    if (i == 3) throw std::runtime_error("frame 3 is corrupt");
    return ++made, i;
  });
  for (int i = 0; i < 3; ++i) EXPECT_EQ(items.Next(), i);
  try {
    items.Next();
    FAIL() << "expected the maker's exception";
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()), "frame 3 is corrupt");
  }
  EXPECT_EQ(made, 3);
}

TEST(OrderedPrefetchTest, DestroyedBeforeEveryItemIsTakenItStops) {
  std::atomic<int> made{0};
  {
    OrderedPrefetch<int> items(1000000, 2, [&](int i) { return ++made, i; });
    EXPECT_EQ(items.Next(), 0);
  }  // Joins without making the rest.
  EXPECT_LE(made, 4);
}

}  // namespace
}  // namespace visloc
