#pragma once
// Stereo rectification of a calibrated pair (OpenCV stereoRectify + remap tables).
//
// After rectification both cameras share the intrinsics `rectified_camera()` (no distortion)
// and differ by a pure translation of `baseline_m()` along the rectified x axis, so a point's
// projections share a row and its depth is Z = f * B / disparity (seed paper 000, eq. 1).
// The rectified left frame is rotated from the raw left frame by `rect_from_left()`: poses
// estimated in rectified coordinates must be rotated back before they are reported in the map
// frame, which product.md defines on the raw left camera.

#include <opencv2/core.hpp>

#include "core/camera/camera.h"
#include "core/geometry/rigid3.h"

namespace visloc {

class StereoRectifier {
 public:
  // `right_from_left` maps left-camera coordinates into the right camera (metres). Throws
  // CheckError when the cameras differ in size or the baseline is degenerate, InputError when
  // the right camera is not to the right of the left one (swapped cameras, a vertical rig).
  StereoRectifier(const Camera& left, const Camera& right,
                  const Rigid3d& right_from_left);

  const Camera& rectified_camera() const { return rectified_camera_; }
  double baseline_m() const { return baseline_m_; }
  // Rotation from the raw left camera frame into the rectified left camera frame.
  const Eigen::Quaterniond& rect_from_left() const { return rect_from_left_; }

  // Remaps raw images (8-bit, the calibrated size) to rectified images on a canvas that holds
  // every raw pixel: `rectified_camera()` keeps only the region valid in both views (OpenCV's
  // alpha = 0), which would cut off the corners of a distorted lens, where many keypoints are.
  // Rectified pixel p is canvas pixel p + canvas_offset_px(). Throws CheckError on a size
  // mismatch.
  void Rectify(const cv::Mat& left_raw, const cv::Mat& right_raw, cv::Mat* left_rect,
               cv::Mat* right_rect) const;
  const Eigen::Vector2d& canvas_offset_px() const { return canvas_offset_px_; }
  cv::Size canvas_size() const { return canvas_size_; }
  // Maps a raw pixel of the left or right image to its rectified pixel; NaN for a fisheye
  // pixel whose ray the rectified (pinhole) camera cannot see.
  Eigen::Vector2d RectifyLeftPixel(const Eigen::Vector2d& raw_pixel) const;
  Eigen::Vector2d RectifyRightPixel(const Eigen::Vector2d& raw_pixel) const;

 private:
  Camera left_;
  Camera right_;
  Camera rectified_camera_;
  double baseline_m_ = 0.0;
  Eigen::Quaterniond rect_from_left_;
  Eigen::Quaterniond rect_from_right_;
  Eigen::Vector2d canvas_offset_px_ = Eigen::Vector2d::Zero();
  cv::Size canvas_size_;
  cv::Mat left_map_x_, left_map_y_, right_map_x_, right_map_y_;
};

}  // namespace visloc
