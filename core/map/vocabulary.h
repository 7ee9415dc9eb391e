#pragma once
// Bag-of-words lookup in a hierarchical k-means vocabulary (Nister and Stewenius, "Scalable
// Recognition with a Vocabulary Tree", CVPR 2006): a descriptor descends from the root to the
// nearest child at each level; the leaf it reaches is its word. Keyframe and query vectors are
// TF-IDF weighted and L1-normalized, and compared with the L1 score
//   s(a, b) = 1 - 0.5 || a - b ||_1  in [0, 1]  (as in DBoW2).

#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>

#include "core/map/map.h"

namespace visloc {

// The word (leaf index, 0-based) of descriptor row `row`.
uint32_t LookupWord(const Vocabulary& vocabulary, const cv::Mat& descriptors, int row);
// The words of every row, as LookupWord gives them; 16-float descriptors (harris_surf16) compare
// with a node's children eight at a time.
std::vector<uint32_t> LookupWords(const Vocabulary& vocabulary, const cv::Mat& descriptors);

// The TF-IDF, L1-normalized vector of a set of descriptors.
BowVector ComputeBow(const Vocabulary& vocabulary, const cv::Mat& descriptors);
// The same from their words (LookupWords), in any order.
BowVector BowFromWords(const Vocabulary& vocabulary, const std::vector<uint32_t>& words);

double BowScore(const BowVector& a, const BowVector& b);

}  // namespace visloc
