#include "mapping/loop_closure.h"

#include <algorithm>

#include "core/util/check.h"
#include "mapping/keyframes.h"

namespace visloc::mapping {

void LoopClosureOptions::Check() const {
  VISLOC_CHECK(radius_m > 0 && max_angle_deg > 0 && search_radius_px > 0,
               "loop closure search ", radius_m, " m, ", max_angle_deg, " deg, ",
               search_radius_px, " px");
  VISLOC_CHECK(
      min_keyframe_gap >= 1 && max_candidates >= 1 && min_inliers >= 4 && cooldown_keyframes >= 0,
      "loop closure counts");
  VISLOC_CHECK(adjust_min_correction_m >= 0 && adjust_min_correction_deg >= 0,
               "loop adjustment thresholds ", adjust_min_correction_m, " m ",
               adjust_min_correction_deg, " deg");
  pose_graph.Check();
}

LoopCloser::LoopCloser(const LoopClosureOptions& options, const FrameTracker& tracker, int window,
                       const RectifiedIntrinsics& intrinsics)
    : options_(options), tracker_(tracker), window_(window), intrinsics_(intrinsics) {
  options_.Check();
  options_.search_radius_px *= ResolutionScale(tracker.view().camera.width());
}

std::vector<int> LoopCloser::OldLandmarks(const SlamState& state, int j, int k) const {
  std::vector<int> old_landmarks;
  for (int l : state.keyframes[j].landmark) {
    if (l < 0 || state.landmarks[l].culled) continue;
    bool seen_now = false;
    for (const auto& [kk, ii] : state.landmarks[l].observations) seen_now |= kk >= k - window_;
    if (!seen_now) old_landmarks.push_back(l);
  }
  return old_landmarks;
}

void LoopCloser::MergeTracks(SlamState* state, int k, const std::vector<LandmarkMatch>& matches,
                             const std::vector<char>& inliers) {
  for (size_t m = 0; m < matches.size(); ++m) {
    if (!inliers[m]) continue;
    const int old_l = matches[m].landmark, i = matches[m].feature;
    const int current_l = state->keyframes[k].landmark[i];
    if (current_l == old_l) continue;
    if (current_l < 0) {
      state->Observe(old_l, k, i);
      continue;
    }
    Landmark& merged = state->landmarks[current_l];
    for (const auto& [kk, ii] : merged.observations) {
      bool old_has_keyframe = false;
      for (const auto& [ok, oi] : state->landmarks[old_l].observations) old_has_keyframe |= ok == kk;
      state->keyframes[kk].landmark[ii] = -1;
      if (!old_has_keyframe) state->Observe(old_l, kk, ii);
    }
    merged.observations.clear();
    merged.culled = true;
  }
}

LoopClosureEvent LoopCloser::TryClose(SlamState* state) {
  LoopClosureEvent event;
  if (!options_.enabled || ++keyframes_since_loop_ <= options_.cooldown_keyframes) return event;
  const int k = static_cast<int>(state->keyframes.size()) - 1;
  const SlamKeyframe& current = state->keyframes[k];
  const Eigen::Vector3d center = CameraCenter(current.cam_from_world);
  std::vector<std::pair<double, int>> candidates;
  for (int j = 0; j < k - options_.min_keyframe_gap; ++j) {
    const Rigid3d& old_pose = state->keyframes[j].cam_from_world;
    const double distance = (CameraCenter(old_pose) - center).norm();
    if (distance < options_.radius_m &&
        AngleBetweenDeg(old_pose, current.cam_from_world) < options_.max_angle_deg) {
      candidates.emplace_back(distance, j);
    }
  }
  std::sort(candidates.begin(), candidates.end());
  for (size_t c = 0; c < std::min<size_t>(options_.max_candidates, candidates.size()); ++c) {
    const std::vector<LandmarkMatch> matches = MatchLandmarks(
        *state, current.grid, current.features.descriptors, tracker_.view(),
        current.cam_from_world, OldLandmarks(*state, candidates[c].second, k),
        options_.search_radius_px, tracker_.options().matching);
    if (static_cast<int>(matches.size()) < options_.min_inliers) continue;
    PnpRansacOptions pnp = tracker_.pnp();
    pnp.min_inliers = options_.min_inliers;
    const PnpResult result = SolvePnpRansac(
        LandmarkObservations(*state, current.left_rect, current.right_x_rect, matches,
                             intrinsics_),
        pnp);
    if (!result.success) continue;
    event.closed = true;
    keyframes_since_loop_ = 0;
    // A large correction is spread over the whole trajectory now, through the pose graph, while
    // it is small enough for bundle adjustment to converge from where the graph leaves it; the
    // local window alone would bend the path at the closure. A small one (most closures: revisits
    // of mapped places) is left to local bundle adjustment and to the global one at the end.
    const double correction_m = (CameraCenter(result.cam_from_world) - center).norm();
    const double correction_deg = AngleBetweenDeg(result.cam_from_world, current.cam_from_world);
    event.adjusted = correction_m >= options_.adjust_min_correction_m ||
                     correction_deg >= options_.adjust_min_correction_deg;
    // The graph's edges are the relative poses before the tracks are merged: the merged tracks
    // join the drifted keyframes to the old ones, which is the loop edges' to say.
    const int old = candidates[c].second;
    std::vector<PoseGraphEdge> edges;
    if (event.adjusted) edges = CovisibilityEdges(*state, old, k + 1, options_.pose_graph);
    // Geometrically verified: the current keypoints are the old landmarks.
    MergeTracks(state, k, matches, result.inlier_mask);
    if (event.adjusted) {
      const PoseGraphEdge closure{
          old, k, result.cam_from_world * state->keyframes[old].cam_from_world.Inverse()};
      CorrectLoop(edges, LoopEdges(*state, closure, window_, edges, options_.pose_graph),
                  options_.pose_graph, state);
    }
    return event;
  }
  return event;
}

}  // namespace visloc::mapping
