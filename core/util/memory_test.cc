#include "core/util/memory.h"

#include <cstdint>

#include <gtest/gtest.h>

namespace visloc {
namespace {

bool OnCacheLine(const void* p) { return reinterpret_cast<uintptr_t>(p) % kCacheLineBytes == 0; }

TEST(CacheLineVectorTest, EveryBufferStartsOnACacheLine) {
  // Sizes that malloc would place 16 bytes off a line among each other.
  std::vector<CacheLineVector<float>> buffers;
  for (size_t n : {1, 3, 5, 17, 100, 1241, 70000}) buffers.emplace_back(n, 1.0f);
  for (const auto& b : buffers) EXPECT_TRUE(OnCacheLine(b.data())) << b.size();
  CacheLineVector<uint8_t> grown;
  for (int i = 0; i < 5000; ++i) {
    grown.push_back(static_cast<uint8_t>(i));
    ASSERT_TRUE(OnCacheLine(grown.data())) << i;
  }
  EXPECT_EQ(grown[4999], static_cast<uint8_t>(4999));  // Growth copies the contents.
}

}  // namespace
}  // namespace visloc
