#include "core/map/descriptor.h"

#include <cmath>

#include <opencv2/core/hal/hal.hpp>

namespace visloc {

float DescriptorDistance(const cv::Mat& a, int row_a, const cv::Mat& b, int row_b) {
  if (a.type() == CV_8U) {
    // Raw rows: no Mat headers on the matching hot path.
    return static_cast<float>(
        cv::hal::normHamming(a.ptr<uchar>(row_a), b.ptr<uchar>(row_b), a.cols));
  }
  const float* x = a.ptr<float>(row_a);
  const float* y = b.ptr<float>(row_b);
  float sum = 0;
  for (int i = 0; i < a.cols; ++i) {
    const float d = x[i] - y[i];
    sum += d * d;
  }
  return std::sqrt(sum);
}

}  // namespace visloc
