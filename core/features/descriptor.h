#pragma once
// Distance between descriptor rows, the one implementation every matcher and the vocabulary
// use: L2 for float rows (CV_32F), Hamming for binary rows (CV_8U). Part of the feature types
// (below the map model, whose points carry descriptors).
//
// Inline, with a fixed-length path for the 16-float rows of harris_surf16: guided matching calls
// it thousands of times per frame (BM_DescriptorDistance/0: 8.6 ns out of line, 7.6 ns now).
// Matching one query against a whole candidate set (relocalization, brute force) goes through
// Float16Columns, which finds the same nearest two sixteen at a time.

#include <cmath>
#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>

#include "core/features/feature_types.h"

namespace visloc {

// Hamming distance of two binary rows of `bytes` bytes.
float HammingDistance(const uchar* a, const uchar* b, int bytes);

// The squared L2 distance of two 16-float descriptors, which DescriptorDistance takes the root
// of. Four independent partial sums, one SIMD register: a single running sum would be a chain
// of 16 dependent additions, which the compiler may not reorder. Lane j sums dimensions j, j + 4,
// j + 8 and j + 12 in that order. Written as 4-float vectors (SSE2, every x86-64): GCC left the
// plain loop scalar, 48 operations where 12 do, in guided matching's innermost loop.
inline float SquaredDistance16(const float* x, const float* y) {
  typedef float Floats4 __attribute__((vector_size(16)));
  Floats4 lanes = {0, 0, 0, 0};
  for (int i = 0; i < 16; i += 4) {
    Floats4 a, b;
    __builtin_memcpy(&a, x + i, sizeof a);
    __builtin_memcpy(&b, y + i, sizeof b);
    const Floats4 d = a - b;
    lanes += d * d;
  }
  return (lanes[0] + lanes[1]) + (lanes[2] + lanes[3]);
}

inline float DescriptorDistance(const cv::Mat& a, int row_a, const cv::Mat& b, int row_b) {
  if (a.type() == CV_8U) return HammingDistance(a.ptr<uchar>(row_a), b.ptr<uchar>(row_b), a.cols);
  const float* x = a.ptr<float>(row_a);
  const float* y = b.ptr<float>(row_b);
  if (a.cols == 16) return std::sqrt(SquaredDistance16(x, y));
  float sum = 0;
  for (int i = 0; i < a.cols; ++i) sum += (x[i] - y[i]) * (x[i] - y[i]);
  return std::sqrt(sum);
}

// Descriptors of 16 floats laid out by dimension (SoA) for one query against many: element
// d * count + j is dimension d of descriptor j. Built once per candidate set.
class Float16Columns {
 public:
  // Rows `rows` of `descriptors` (CV_32F, 16 columns).
  Float16Columns(const cv::Mat& descriptors, const std::vector<uint32_t>& rows);
  int size() const { return count_; }
  // The nearest two descriptors to `query`, exactly as NearestTwo::Offer of each distance
  // DescriptorDistance(query, descriptor j) in order j = 0, 1, ... leaves them (the first of
  // equal bests, a tie's twin as the second), bit for bit: the same operations in the same order
  // for each distance, but sixteen descriptors at a time (no sum runs across a register), and
  // no distance stored. Relocalization and the brute-force baseline match every keypoint of a
  // query against hundreds of points.
  NearestTwo Nearest(const float* query) const;
  // The index in [first, first + count) of the descriptor nearest to `query`, the first of equal
  // distances, each distance DescriptorDistance's bit for bit (vocabulary lookups: a node's
  // children are consecutive rows); -1 when count is 0.
  int NearestOf(const float* query, int first, int count) const;
  // The squared distances of `query` to descriptors [first, first + n) into out[0, n):
  // SquaredDistance16's, bit for bit, sixteen at a time (guided matching offers a keypoint's
  // neighbours in runs of consecutive descriptors). `out` must have room for n + 15 floats: a
  // vector is stored whole, past n.
  void SquaredDistances(const float* query, int first, int n, float* out) const;

 private:
  int count_ = 0;
  std::vector<float> columns_;
};

}  // namespace visloc
