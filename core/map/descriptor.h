#pragma once
// Distance between descriptor rows, the one implementation every matcher and the vocabulary
// use: L2 for float rows (CV_32F), Hamming for binary rows (CV_8U). It sits with the map model
// because descriptors are part of it; core/features re-exports it.

#include <opencv2/core.hpp>

namespace visloc {

float DescriptorDistance(const cv::Mat& a, int row_a, const cv::Mat& b, int row_b);

}  // namespace visloc
