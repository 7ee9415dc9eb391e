#pragma once
// One query image's features, prepared for matching: keypoints in raw (distorted) pixels, their
// undistorted normalized coordinates for the pose solvers, and a grid over the image for radius
// searches around projected map points.

#include <vector>

#include <Eigen/Core>

#include "core/camera/camera.h"
#include "core/features/descriptor_matching.h"
#include "core/features/features.h"

namespace visloc {

class QueryFrame {
 public:
  // `cell_px` is the grid's cell size; radius searches look at the cells a disc touches.
  // Keypoints with no ray in front of the camera (a fisheye's rim beyond 90 degrees) are
  // left out.
  QueryFrame(FeatureSet features, const Camera& camera, int cell_px = 16);

  const FeatureSet& features() const { return features_; }
  size_t size() const { return features_.size(); }
  // Undistorted normalized image coordinates (x/z, y/z) of keypoint i.
  const Eigen::Vector2d& normalized(int i) const { return normalized_[i]; }
  // The lens's pixel scale at keypoint i (Camera::PixelScale).
  double pixel_scale(int i) const { return pixel_scale_[i]; }
  // The keypoints' raw pixels, bucketed for radius searches.
  const KeypointGrid& grid() const { return grid_; }

 private:
  FeatureSet features_;
  std::vector<Eigen::Vector2d> normalized_;
  std::vector<double> pixel_scale_;
  KeypointGrid grid_;
};

}  // namespace visloc
