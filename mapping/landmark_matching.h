#pragma once
// Guided matching of landmarks to one view's keypoints (a new frame, or a keyframe during loop
// closure), in the rectified left image: each landmark is projected with the view's pose and
// matched by the descriptor of its latest observation (MatchGuided, the matcher localization
// uses too).

#include <vector>

#include <Eigen/Geometry>

#include "core/camera/camera.h"
#include "core/camera/stereo_rectifier.h"
#include "core/features/descriptor_matching.h"
#include "core/geometry/rigid3.h"
#include "mapping/slam_state.h"

namespace visloc::mapping {

struct LandmarkMatch {
  int landmark;
  int feature;  // Keypoint index in the view.
};

// Where a view's keypoints can be, in rectified pixels of the left camera: the rectified
// camera (no distortion) and the region its raw image covers, which reaches beyond the
// rectified image's bounds at the corners of a distorted lens (StereoRectifier's canvas).
struct RectifiedView {
  Camera camera;
  Eigen::AlignedBox2d region;
};
RectifiedView ViewOf(const StereoRectifier& rectifier);

// `grid` holds the view's rectified keypoints and `descriptors` their descriptors. When
// `in_view` is given, it receives the landmarks that project into the view's region.
std::vector<LandmarkMatch> MatchLandmarks(const SlamState& state, const KeypointGrid& grid,
                                          const cv::Mat& descriptors, const RectifiedView& view,
                                          const Rigid3d& cam_from_world,
                                          const std::vector<int>& landmarks, double radius_px,
                                          const DescriptorMatchOptions& options,
                                          std::vector<int>* in_view = nullptr);

}  // namespace visloc::mapping
