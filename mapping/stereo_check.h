#pragma once
// Whether a calibrated stereo pair will map, measured on its images without trusting the
// calibration: the epipolar residual (left and right keypoints matched by descriptor alone,
// anywhere in the image, then the difference of their rectified rows: a sound calibration gives
// a fraction of a pixel, a wrong T_BS or wrong intrinsics several pixels), what the row search
// of the mapper then finds (StereoMatchStats), and the depths of the stereo points.

#include <cstdint>
#include <vector>

#include "core/camera/stereo_rectifier.h"
#include "core/features/features.h"
#include "mapping/stereo_frame.h"

namespace visloc::mapping {

struct StereoPairCheck {
  int left_keypoints = 0;
  int right_keypoints = 0;
  std::vector<double> row_difference_px;  // |left row - right row| per descriptor match.
  std::vector<double> disparity_px;       // Of the same matches (left x - right x, rectified).
  StereoMatchStats stereo;                // The mapper's row search.
  std::vector<double> depth_m;            // Of its stereo points.
};

StereoPairCheck CheckStereoPair(const cv::Mat& left_raw, const cv::Mat& right_raw,
                                const FeatureExtractor& extractor,
                                const StereoRectifier& rectifier,
                                const StereoMatchOptions& options);

// The value at quantile q in [0, 1] of `values` (nearest rank), NaN when empty.
double Quantile(std::vector<double> values, double q);

}  // namespace visloc::mapping
