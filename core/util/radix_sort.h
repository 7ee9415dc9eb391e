#pragma once
// Sorting 64-bit keys by least-significant-digit radix sort, for the per-frame orderings of a few
// hundred to a few thousand items (corner candidates by response, predicted points by
// probability): eight linear passes over bytes order them several times faster than comparisons.
// Callers pack what they sort by into the key's high bits and a tie-breaking index into its low
// bits, so the order is total and the same on every platform.

#include <cstdint>
#include <vector>

namespace visloc {

// `keys` in ascending order. A byte that every key shares (an index's high bytes, say) costs no
// pass.
void RadixSort(std::vector<uint64_t>* keys);

// The key that orders a non-negative float descending: larger values give smaller keys, and
// equal values compare by `tie` ascending (IEEE bits of non-negative floats order as the floats).
uint64_t DescendingKey(float non_negative, uint32_t tie);
// The value a DescendingKey was made of.
float DescendingKeyValue(uint64_t key);

}  // namespace visloc
