#include "mapping/frame_tracker.h"

#include <cmath>

#include "core/util/check.h"

namespace visloc::mapping {

void TrackingOptions::Check() const {
  matching.Check();
  VISLOC_CHECK(search_radius_px > 0 && refine_radius_px > 0, "tracking radii ", search_radius_px,
               ", ", refine_radius_px, " px");
  VISLOC_CHECK(max_error_px > 0 && min_inliers >= 4, "tracking thresholds ", max_error_px, " px, ",
               min_inliers, " inliers");
}

std::vector<PoseObservation> LandmarkObservations(const SlamState& state,
                                                  const std::vector<Eigen::Vector2d>& left_rect,
                                                  const std::vector<double>& right_x_rect,
                                                  const std::vector<LandmarkMatch>& matches,
                                                  const RectifiedIntrinsics& k) {
  std::vector<PoseObservation> observations;
  observations.reserve(matches.size());
  for (const LandmarkMatch& m : matches) {
    PoseObservation o;
    o.point_in_world = state.landmarks[m.landmark].position_in_world;
    o.normalized = Eigen::Vector2d((left_rect[m.feature].x() - k.cx) / k.f,
                                   (left_rect[m.feature].y() - k.cy) / k.f);
    if (std::isfinite(right_x_rect[m.feature])) {
      o.has_right = true;
      o.right_x_normalized = (right_x_rect[m.feature] - k.cx) / k.f;
    }
    observations.push_back(o);
  }
  return observations;
}

FrameTracker::FrameTracker(const TrackingOptions& options, const RectifiedView& view,
                           const RectifiedIntrinsics& intrinsics, double disparity_weight)
    : options_(options), view_(view), intrinsics_(intrinsics) {
  options_.Check();
  const double scale = ResolutionScale(view.camera.width());
  options_.search_radius_px *= scale;
  options_.refine_radius_px *= scale;
  pnp_.max_error_px = options_.max_error_px;
  pnp_.min_inliers = options_.min_inliers;
  pnp_.refine.focal_px = intrinsics.f;
  pnp_.refine.baseline_m = intrinsics.baseline_m;
  pnp_.refine.disparity_weight = disparity_weight;
}

std::vector<LandmarkMatch> FrameTracker::Match(const SlamState& state, const StereoFrame& frame,
                                               const Rigid3d& cam_from_world,
                                               const std::vector<int>& landmarks, double radius_px,
                                               std::vector<int>* in_view) const {
  return MatchLandmarks(state, frame.grid, frame.left.descriptors, view_, cam_from_world, landmarks,
                        radius_px, options_.matching, in_view);
}

std::vector<LandmarkMatch> FrameTracker::MatchWithoutPrediction(const SlamState& state,
                                                                const StereoFrame& frame) const {
  if (state.keyframes.empty()) return {};
  std::vector<int> landmarks;
  cv::Mat descriptors;
  for (int l : state.keyframes.back().landmark) {
    if (l < 0 || state.landmarks[l].culled) continue;
    const auto& [k, i] = state.landmarks[l].observations.back();
    landmarks.push_back(l);
    descriptors.push_back(state.keyframes[k].features.descriptors.row(i));
  }
  std::vector<LandmarkMatch> matches;
  for (const auto& [a, b] :
       MatchMutualNearest(descriptors, frame.left.descriptors, options_.matching)) {
    matches.push_back({landmarks[a], b});
  }
  return matches;
}

namespace {

// The matches' observations, their keypoints' stereo matches searched first.
std::vector<PoseObservation> SearchedObservations(const SlamState& state,
                                                  const std::vector<LandmarkMatch>& matches,
                                                  const RectifiedIntrinsics& intrinsics,
                                                  StereoFrameSearch* frame) {
  std::vector<int> features;
  features.reserve(matches.size());
  for (const LandmarkMatch& m : matches) features.push_back(m.feature);
  frame->Search(features);
  return LandmarkObservations(state, frame->frame().left_rect, frame->frame().right_x_rect, matches,
                              intrinsics);
}

}  // namespace

TrackResult FrameTracker::Track(const SlamState& state, StereoFrameSearch* search,
                                const Rigid3d& predicted, const std::vector<int>& landmarks,
                                uint64_t seed) const {
  const StereoFrame& frame = search->frame();
  TrackResult result;
  result.cam_from_world = predicted;
  std::vector<LandmarkMatch> matches =
      Match(state, frame, predicted, landmarks, options_.search_radius_px);
  PnpRansacOptions pnp = pnp_;
  pnp.seed = seed;
  PnpResult ransac = SolvePnpRansac(SearchedObservations(state, matches, intrinsics_, search), pnp);
  if (!ransac.success) {
    matches = MatchWithoutPrediction(state, frame);
    ransac = SolvePnpRansac(SearchedObservations(state, matches, intrinsics_, search), pnp);
  }
  if (!ransac.success) return result;
  // Re-match with the estimated pose in a tight radius: more tracks, fewer outliers.
  matches = Match(state, frame, ransac.cam_from_world, landmarks, options_.refine_radius_px,
                  &result.in_view);
  const std::vector<PoseObservation> observations =
      SearchedObservations(state, matches, intrinsics_, search);
  result.success = true;
  result.cam_from_world = RefinePose(ransac.cam_from_world, observations, pnp.refine);
  const PoseProjector projector(result.cam_from_world, pnp.refine);
  const double max_error_sq = options_.max_error_px * options_.max_error_px;
  for (size_t j = 0; j < matches.size(); ++j) {
    if (projector.SquaredErrorPx(observations[j]) <= max_error_sq) {
      result.tracked.push_back(matches[j]);
    }
  }
  return result;
}

}  // namespace visloc::mapping
