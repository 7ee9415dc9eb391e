#include "core/map/vocabulary.h"

#include <algorithm>
#include <cmath>
#include <map>

#include "core/features/descriptor.h"
#include "core/util/check.h"

namespace visloc {
uint32_t LookupWord(const Vocabulary& vocabulary, const cv::Mat& descriptors, int row) {
  VISLOC_CHECK(!vocabulary.empty(), "empty vocabulary");
  // Node index within its level; the rows of level l start at sum_{m<l} b^m (level 1 at 0).
  int index = 0, level_start = 0, level_size = vocabulary.branching;
  for (int level = 0; level < vocabulary.depth; ++level) {
    int best = 0;
    float best_distance = std::numeric_limits<float>::max();
    for (int c = 0; c < vocabulary.branching; ++c) {
      const int node = level_start + index * vocabulary.branching + c;
      const float d = DescriptorDistance(descriptors, row, vocabulary.centroids, node);
      if (d < best_distance) {
        best_distance = d;
        best = c;
      }
    }
    index = index * vocabulary.branching + best;
    level_start += level_size;
    level_size *= vocabulary.branching;
  }
  return static_cast<uint32_t>(index);
}

BowVector ComputeBow(const Vocabulary& vocabulary, const cv::Mat& descriptors) {
  std::map<uint32_t, float> counts;
  for (int r = 0; r < descriptors.rows; ++r) counts[LookupWord(vocabulary, descriptors, r)] += 1.0f;
  BowVector vector;
  float total = 0;
  for (const auto& [word, count] : counts) {
    const float weight = count * vocabulary.word_weights[word];
    if (weight <= 0) continue;
    vector.emplace_back(word, weight);
    total += weight;
  }
  for (auto& [word, weight] : vector) weight /= total;
  return vector;
}

double BowScore(const BowVector& a, const BowVector& b) {
  // For L1-normalized vectors, ||a - b||_1 = 2 - sum over common words of (|a|+|b|-|a-b|).
  double common = 0;
  size_t i = 0, j = 0;
  while (i < a.size() && j < b.size()) {
    if (a[i].first == b[j].first) {
      common += std::abs(a[i].second) + std::abs(b[j].second) - std::abs(a[i].second - b[j].second);
      ++i;
      ++j;
    } else if (a[i].first < b[j].first) {
      ++i;
    } else {
      ++j;
    }
  }
  return 0.5 * common;
}

}  // namespace visloc
