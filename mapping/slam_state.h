#pragma once
// The map builder's working state: keyframes with their features and landmarks (3D points
// with feature tracks across keyframes). Frames: `world` is the rectified left camera frame of
// the first frame; keyframe poses are cam_from_world of the rectified left camera.

#include <cstdint>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "core/features/feature_types.h"
#include "core/features/descriptor_matching.h"
#include "core/geometry/rigid3.h"

namespace visloc::mapping {

struct SlamKeyframe {
  int64_t timestamp_ns = 0;
  Rigid3d cam_from_world;
  FeatureSet features;                     // Raw left image keypoints and descriptors.
  std::vector<Eigen::Vector2d> left_rect;  // Rectified keypoint positions.
  KeypointGrid grid;                       // The rectified positions, for radius searches.
  std::vector<double> right_x_rect;        // Stereo match x (rectified), NaN when none.
  std::vector<int> landmark;               // Landmark of each keypoint, -1 when none.
};

struct Landmark {
  Eigen::Vector3d position_in_world = Eigen::Vector3d::Zero();
  std::vector<std::pair<int, int>> observations;  // (keyframe, keypoint index)
  bool culled = false;
  // Tracked frames (keyframes or not) in whose view the landmark projected, and in how many of
  // them it was found: how reliable it is beyond its keyframe observations.
  int frames_in_view = 0;
  int frames_found = 0;
};

struct SlamState {
  std::vector<SlamKeyframe> keyframes;
  std::vector<Landmark> landmarks;

  // Adds an observation of landmark `l` by keyframe `k`'s keypoint `i` (both ways).
  void Observe(int l, int k, int i) {
    landmarks[l].observations.emplace_back(k, i);
    keyframes[k].landmark[i] = l;
  }
};

}  // namespace visloc::mapping
