#pragma once
// Distance between descriptor rows, the one implementation every matcher and the vocabulary
// use: L2 for float rows (CV_32F), Hamming for binary rows (CV_8U). It sits with the map model
// because descriptors are part of it; core/features re-exports it.
//
// Inline, with a fixed-length path for the 16-float rows of harris_surf16: guided matching calls
// it thousands of times per frame (BM_DescriptorDistance/0: 8.6 ns out of line, 7.6 ns now).

#include <cmath>

#include <opencv2/core.hpp>

namespace visloc {

// Hamming distance of two binary rows of `bytes` bytes.
float HammingDistance(const uchar* a, const uchar* b, int bytes);

inline float DescriptorDistance(const cv::Mat& a, int row_a, const cv::Mat& b, int row_b) {
  if (a.type() == CV_8U) return HammingDistance(a.ptr<uchar>(row_a), b.ptr<uchar>(row_b), a.cols);
  const float* x = a.ptr<float>(row_a);
  const float* y = b.ptr<float>(row_b);
  if (a.cols == 16) {
    // Four independent partial sums, one SIMD register: a single running sum would be a chain
    // of 16 dependent additions, which the compiler may not reorder.
    float lanes[4] = {0, 0, 0, 0};
    for (int i = 0; i < 16; i += 4) {
      for (int j = 0; j < 4; ++j) lanes[j] += (x[i + j] - y[i + j]) * (x[i + j] - y[i + j]);
    }
    return std::sqrt((lanes[0] + lanes[1]) + (lanes[2] + lanes[3]));
  }
  float sum = 0;
  for (int i = 0; i < a.cols; ++i) sum += (x[i] - y[i]) * (x[i] - y[i]);
  return std::sqrt(sum);
}

}  // namespace visloc
