#pragma once
// One stereo frame prepared for mapping: features of the raw left and right images, their
// rectified positions, stereo matches along rectified rows and the triangulated points.
//
// Descriptors are computed on the raw images (as localization will see them); geometry uses
// rectified coordinates, in which the right camera is the left one shifted by the baseline
// along +x (seed paper 000, eqs. 1-3):
//   Z = f B / d,  X = (u - cx) Z / f,  Y = (v - cy) Z / f,  d = u_left - u_right.

#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "core/camera/stereo_rectifier.h"
#include "core/features/features.h"
#include "core/features/guided_matching.h"

namespace visloc::mapping {

struct StereoMatchOptions {
  double max_row_difference_px = 1.0;    // Rectified rows must agree (calibration residual).
  double min_depth_m = 0.3;              // Nearer points are out of range.
  double max_depth_m = 12.0;             // Farther points have too little disparity to triangulate.
  // Left and right descriptors of one point, seen from a few centimetres apart at the same
  // moment, are closer than across frames: stricter than tracking.
  DescriptorMatchOptions matching{0.6f, 64.0f, 0.8f};
  // Disparity refinement: the left patch is aligned along the right image's row by Gauss-Newton
  // on the zero-mean SSD, with the disparity allowed to vary linearly across the patch (slanted
  // surfaces); this measures disparity to a few hundredths of a pixel where independent corner
  // positions disagree by a tenth. 0 disables it.
  int refine_patch_radius_px = 7;
  double refine_max_shift_px = 1.0;  // Larger corrections mean a wrong match: rejected.
  void Check() const;
};

struct StereoFrame {
  FeatureSet left;                             // Raw left image features.
  std::vector<Eigen::Vector2d> left_rect;      // Rectified positions of left keypoints.
  KeypointGrid grid;                           // left_rect, for radius searches.
  std::vector<double> right_x_rect;            // Matched right rectified x, or NaN.
  std::vector<Eigen::Vector3d> point_in_rect;  // Triangulated point (rectified left frame), or NaN.
  int stereo_matches = 0;
  bool HasDepth(size_t i) const { return point_in_rect[i].allFinite(); }
};

// Refines disparity `d` of rectified left pixel (x, y) by aligning a (2r+1)^2 patch of `left`
// with `right` along the row (both CV_32F rectified images; `right_gradient_x` is the right
// image's central-difference x gradient). Returns false when the patch leaves the image or the
// alignment does not converge.
bool RefineDisparity(const cv::Mat& left, const cv::Mat& right, const cv::Mat& right_gradient_x,
                     double x, double y, int radius, double* d);

StereoFrame BuildStereoFrame(const cv::Mat& left_raw, const cv::Mat& right_raw,
                             const FeatureExtractor& extractor, const StereoRectifier& rectifier,
                             const StereoMatchOptions& options);

}  // namespace visloc::mapping
