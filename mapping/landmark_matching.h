#pragma once
// Guided matching of landmarks to one view's keypoints (a new frame, or a keyframe during loop
// closure), in the rectified left image: each landmark is projected with the view's pose and
// matched by the descriptor of its latest observation (MatchGuided, the matcher localization
// uses too).

#include <vector>

#include "core/camera/pinhole_camera.h"
#include "core/features/guided_matching.h"
#include "core/geometry/rigid3.h"
#include "mapping/slam_state.h"

namespace visloc::mapping {

struct LandmarkMatch {
  int landmark;
  int feature;  // Keypoint index in the view.
};

// `grid` holds the view's rectified keypoints and `descriptors` their descriptors;
// `rectified_camera` is the rectified left camera (no distortion).
std::vector<LandmarkMatch> MatchLandmarks(const SlamState& state, const KeypointGrid& grid,
                                          const cv::Mat& descriptors,
                                          const PinholeCamera& rectified_camera,
                                          const Rigid3d& cam_from_world,
                                          const std::vector<int>& landmarks, double radius_px,
                                          const DescriptorMatchOptions& options);

}  // namespace visloc::mapping
