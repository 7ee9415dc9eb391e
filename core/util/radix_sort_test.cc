#include "core/util/radix_sort.h"

#include <algorithm>
#include <tuple>

#include <gtest/gtest.h>

#include "core/util/random.h"

namespace visloc {
namespace {

TEST(RadixSortTest, OrdersLikeStdSortIncludingSharedBytesAndDuplicates) {
  Rng rng(5);
  for (const int count : {0, 1, 2, 700, 5000}) {
    std::vector<uint64_t> keys;
    for (int i = 0; i < count; ++i) {
      // Random high bits, an index-like low part whose high bytes every key shares, repeats.
      const uint64_t high = static_cast<uint64_t>(rng.Uniform(0, 1e9));
      keys.push_back((high << 32) | static_cast<uint64_t>(i % 300));
    }
    std::vector<uint64_t> expected = keys;
    std::sort(expected.begin(), expected.end());
    RadixSort(&keys);
    EXPECT_EQ(keys, expected) << count << " keys";
  }
}

TEST(RadixSortTest, DescendingKeysOrderByValueDescendingThenTieAscending) {
  const std::vector<std::pair<float, uint32_t>> items = {
      {0.5f, 3}, {0.25f, 1}, {0.5f, 0}, {1.0f, 7}, {0.0f, 2}, {3e-8f, 9}, {0.25f, 0}};
  std::vector<uint64_t> keys;
  for (const auto& [value, tie] : items) keys.push_back(DescendingKey(value, tie));
  RadixSort(&keys);
  std::vector<std::pair<float, uint32_t>> expected = items;
  std::sort(expected.begin(), expected.end(), [](const auto& a, const auto& b) {
    return a.first > b.first || (a.first == b.first && a.second < b.second);
  });
  for (size_t i = 0; i < keys.size(); ++i) {
    EXPECT_EQ(static_cast<uint32_t>(keys[i]), expected[i].second) << "position " << i;
    EXPECT_EQ(DescendingKeyValue(keys[i]), expected[i].first) << "position " << i;
  }
}

}  // namespace
}  // namespace visloc
