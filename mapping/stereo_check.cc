#include "mapping/stereo_check.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/features/descriptor_matching.h"

namespace visloc::mapping {

double Quantile(std::vector<double> values, double q) {
  if (values.empty()) return std::numeric_limits<double>::quiet_NaN();
  const size_t rank = std::min(values.size() - 1, static_cast<size_t>(q * (values.size() - 1) + 0.5));
  std::nth_element(values.begin(), values.begin() + rank, values.end());
  return values[rank];
}

StereoPairCheck CheckStereoPair(const cv::Mat& left_raw, const cv::Mat& right_raw,
                                const FeatureExtractor& extractor,
                                const StereoRectifier& rectifier,
                                const StereoMatchOptions& options) {
  StereoPairCheck check;
  const StereoFrame frame = BuildStereoFrame(left_raw, right_raw, extractor, rectifier, options);
  const FeatureSet right = extractor.Extract(right_raw);
  check.left_keypoints = static_cast<int>(frame.left.size());
  check.right_keypoints = static_cast<int>(right.size());
  check.stereo = frame.stats;
  for (size_t i = 0; i < frame.point_in_rect.size(); ++i) {
    if (frame.HasDepth(i)) check.depth_m.push_back(frame.point_in_rect[i].z());
  }
  // Strict descriptor thresholds: the two views of one moment are near copies of each other.
  const DescriptorMatchOptions strict{0.5f, 64.0f, 0.7f};
  for (const auto& [i, j] :
       MatchMutualNearest(frame.left.descriptors, right.descriptors, strict)) {
    const Eigen::Vector2d l = frame.left_rect[i];
    const Eigen::Vector2d r = rectifier.RectifyRightPixel(right.keypoints[j].pixel.cast<double>());
    check.row_difference_px.push_back(std::abs(l.y() - r.y()));
    check.disparity_px.push_back(l.x() - r.x());
  }
  return check;
}

}  // namespace visloc::mapping
