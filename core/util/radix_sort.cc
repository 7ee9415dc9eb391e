#include "core/util/radix_sort.h"

#include <algorithm>
#include <array>
#include <cstring>

namespace visloc {

void RadixSort(std::vector<uint64_t>* keys) {
  std::vector<uint64_t> scratch(keys->size());
  for (int shift = 0; shift < 64; shift += 8) {
    std::array<size_t, 257> start{};
    for (uint64_t key : *keys) ++start[((key >> shift) & 0xff) + 1];
    if (std::find(start.begin() + 1, start.end(), keys->size()) != start.end()) continue;
    for (int b = 1; b <= 256; ++b) start[b] += start[b - 1];
    for (uint64_t key : *keys) scratch[start[(key >> shift) & 0xff]++] = key;
    keys->swap(scratch);
  }
}

uint64_t DescendingKey(float non_negative, uint32_t tie) {
  uint32_t bits;
  std::memcpy(&bits, &non_negative, sizeof bits);
  return (static_cast<uint64_t>(~bits) << 32) | tie;
}

float DescendingKeyValue(uint64_t key) {
  const uint32_t bits = ~static_cast<uint32_t>(key >> 32);
  float value;
  std::memcpy(&value, &bits, sizeof value);
  return value;
}

}  // namespace visloc
