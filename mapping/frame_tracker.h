#pragma once
// Tracking of one stereo frame against the landmarks of the recent keyframes (seed paper 000,
// sec. 3): landmarks projected with a predicted pose are matched within a search radius
// (MatchLandmarks), PnP RANSAC with the rectified stereo residuals gives a pose, every landmark
// is re-matched in a tight radius around it, and Levenberg-Marquardt refines the pose on the
// matches within the inlier threshold, which are the frame's tracked landmarks.
//
// When the prediction is too far off for the search radius (the second frame, whose motion
// nothing predicts; a car at 2 m and 5 degrees a frame; a jolt), the last keyframe's landmarks
// are matched by descriptor alone (mutual nearest neighbours) and RANSAC runs on those.

#include <cstdint>
#include <vector>

#include "core/camera/camera.h"
#include "core/estimators/pnp_ransac.h"
#include "mapping/landmark_matching.h"
#include "mapping/reprojection_cost.h"
#include "mapping/stereo_frame.h"

namespace visloc::mapping {

struct TrackingOptions {
  // Radii in pixels at 320 pixels of image width (the paper's), scaled with the image width:
  // image motion between frames, and the error of a pose projected, grow with resolution.
  double search_radius_px = 15.0;  // Around the constant-velocity prediction (paper: 15 px).
  double refine_radius_px = 4.0;   // Around the RANSAC pose.
  DescriptorMatchOptions matching;
  double max_error_px = 2.0;  // Inlier threshold of RANSAC and of the tracked landmarks.
  int min_inliers = 15;       // A pose needs this many RANSAC inliers.
  void Check() const;
};

struct TrackResult {
  bool success = false;
  Rigid3d cam_from_world;              // The prediction when tracking failed.
  std::vector<LandmarkMatch> tracked;  // Matches within max_error_px of the refined pose.
  std::vector<int> in_view;            // Landmarks that project into the view at that pose.
};

class FrameTracker {
 public:
  // `view` and `intrinsics` describe the rectified left camera; `disparity_weight` weighs the
  // disparity residuals as bundle adjustment does.
  FrameTracker(const TrackingOptions& options, const RectifiedView& view,
               const RectifiedIntrinsics& intrinsics, double disparity_weight);

  // Tracks the frame from the `predicted` pose against `landmarks` of `state`, searching the
  // stereo matches of the keypoints it matches to landmarks (those alone: a frame that becomes
  // a keyframe has the rest searched then). `seed` makes the RANSAC sampling repeatable per
  // frame.
  TrackResult Track(const SlamState& state, StereoFrameSearch* frame, const Rigid3d& predicted,
                    const std::vector<int>& landmarks, uint64_t seed) const;

  // The PnP options tracking uses (loop closure verifies with the same, other thresholds aside).
  const PnpRansacOptions& pnp() const { return pnp_; }
  const TrackingOptions& options() const { return options_; }
  const RectifiedView& view() const { return view_; }

 private:
  // The last keyframe's landmarks matched to the frame's keypoints by descriptor alone.
  std::vector<LandmarkMatch> MatchWithoutPrediction(const SlamState& state,
                                                    const StereoFrame& frame) const;
  std::vector<LandmarkMatch> Match(const SlamState& state, const StereoFrame& frame,
                                   const Rigid3d& cam_from_world, const std::vector<int>& landmarks,
                                   double radius_px, std::vector<int>* in_view = nullptr) const;

  TrackingOptions options_;  // Radii scaled to the image width.
  RectifiedView view_;
  RectifiedIntrinsics intrinsics_;
  PnpRansacOptions pnp_;
};

// Pose observations of `frame`'s keypoints matched to landmarks, in rectified normalized
// coordinates, with the right image's x where the keypoint has a stereo match.
std::vector<PoseObservation> LandmarkObservations(const SlamState& state,
                                                  const std::vector<Eigen::Vector2d>& left_rect,
                                                  const std::vector<double>& right_x_rect,
                                                  const std::vector<LandmarkMatch>& matches,
                                                  const RectifiedIntrinsics& intrinsics);

// The factor that converts pixel radii given at 320 pixels of width to `width`.
inline double ResolutionScale(int width) { return width / 320.0; }

}  // namespace visloc::mapping
