#include "core/map/vocabulary.h"

#include <algorithm>
#include <cmath>

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

std::vector<uint32_t> LookupWords(const Vocabulary& vocabulary, const cv::Mat& descriptors) {
  VISLOC_CHECK(!vocabulary.empty(), "empty vocabulary");
  std::vector<uint32_t> words(descriptors.rows);
  const bool float16 = descriptors.type() == CV_32F && descriptors.cols == 16 &&
                       vocabulary.centroids.type() == CV_32F && vocabulary.centroids.cols == 16;
  if (!float16) {
    for (int r = 0; r < descriptors.rows; ++r) words[r] = LookupWord(vocabulary, descriptors, r);
    return words;
  }
  std::vector<uint32_t> all(vocabulary.centroids.rows);
  for (size_t i = 0; i < all.size(); ++i) all[i] = static_cast<uint32_t>(i);
  const Float16Columns centroids(vocabulary.centroids, all);
  for (int r = 0; r < descriptors.rows; ++r) {
    const float* query = descriptors.ptr<float>(r);
    // As LookupWord: node index within its level, level l's rows from sum_{m<l} b^m on.
    int index = 0, level_start = 0, level_size = vocabulary.branching;
    for (int level = 0; level < vocabulary.depth; ++level) {
      const int first = level_start + index * vocabulary.branching;
      // No nearest child (every distance NaN): the first, as LookupWord takes it.
      const int best = std::max(centroids.NearestOf(query, first, vocabulary.branching), first);
      index = index * vocabulary.branching + (best - first);
      level_start += level_size;
      level_size *= vocabulary.branching;
    }
    words[r] = static_cast<uint32_t>(index);
  }
  return words;
}

BowVector ComputeBow(const Vocabulary& vocabulary, const cv::Mat& descriptors) {
  return BowFromWords(vocabulary, LookupWords(vocabulary, descriptors));
}

BowVector BowFromWords(const Vocabulary& vocabulary, const std::vector<uint32_t>& words) {
  // Counted per word, then taken in word order (a vocabulary has a few hundred to a few
  // thousand words, fewer than a sort of an image's words costs).
  std::vector<uint32_t> counts(vocabulary.word_weights.size(), 0);
  for (uint32_t word : words) {
    VISLOC_CHECK(word < counts.size(), "word ", word, " of ", counts.size());
    ++counts[word];
  }
  BowVector vector;
  float total = 0;
  for (uint32_t word = 0; word < counts.size(); ++word) {
    if (counts[word] == 0) continue;
    const float weight = static_cast<float>(counts[word]) * vocabulary.word_weights[word];
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
