#include "mapping/keyframes.h"

#include <algorithm>

#include "core/util/check.h"

namespace visloc::mapping {

void KeyframeOptions::Check() const {
  VISLOC_CHECK(translation_m > 0 && rotation_deg > 0 && min_tracked >= 0, "keyframe thresholds ",
               translation_m, " m, ", rotation_deg, " deg, ", min_tracked, " tracked");
  VISLOC_CHECK(window >= 2 && free >= 1 && free < window, "local BA window ", window, " free ",
               free);
  VISLOC_CHECK(local_ba_function_tolerance > 0 && local_ba_function_tolerance < 1,
               "local BA function tolerance ", local_ba_function_tolerance);
}

double AngleBetweenDeg(const Rigid3d& a, const Rigid3d& b) {
  return RotationAngleDeg(a.rotation.conjugate() * b.rotation);
}

bool NeedsKeyframe(const KeyframeOptions& options, const Rigid3d& cam_from_world,
                   const Rigid3d& keyframe_cam_from_world, int tracked) {
  const double moved =
      (CameraCenter(cam_from_world) - CameraCenter(keyframe_cam_from_world)).norm();
  const double turned = AngleBetweenDeg(cam_from_world, keyframe_cam_from_world);
  return moved > options.translation_m || turned > options.rotation_deg ||
         tracked < options.min_tracked;
}

void AddKeyframe(SlamState* state, int64_t timestamp_ns, StereoFrame&& frame,
                 const Rigid3d& cam_from_world, const std::vector<LandmarkMatch>& tracked) {
  SlamKeyframe keyframe;
  keyframe.timestamp_ns = timestamp_ns;
  keyframe.cam_from_world = cam_from_world;
  keyframe.left_rect = std::move(frame.left_rect);
  keyframe.grid = std::move(frame.grid);
  keyframe.right_x_rect = std::move(frame.right_x_rect);
  keyframe.landmark.assign(frame.left.size(), -1);
  keyframe.features = std::move(frame.left);
  state->keyframes.push_back(std::move(keyframe));
  const int k = static_cast<int>(state->keyframes.size()) - 1;
  for (const LandmarkMatch& m : tracked) state->Observe(m.landmark, k, m.feature);
  const Rigid3d world_from_cam = cam_from_world.Inverse();
  const std::vector<Eigen::Vector3d>& points = frame.point_in_rect;
  for (size_t i = 0; i < points.size(); ++i) {
    if (state->keyframes[k].landmark[i] >= 0 || !points[i].allFinite()) continue;
    Landmark landmark;
    landmark.position_in_world = world_from_cam * points[i];
    state->landmarks.push_back(landmark);
    state->Observe(static_cast<int>(state->landmarks.size()) - 1, k, static_cast<int>(i));
  }
}

std::vector<int> RecentLandmarks(const SlamState& state, int window) {
  std::vector<int> landmarks;
  const int n = static_cast<int>(state.keyframes.size());
  for (int k = std::max(0, n - window); k < n; ++k) {
    for (int l : state.keyframes[k].landmark) {
      if (l >= 0 && !state.landmarks[l].culled) landmarks.push_back(l);
    }
  }
  std::sort(landmarks.begin(), landmarks.end());
  landmarks.erase(std::unique(landmarks.begin(), landmarks.end()), landmarks.end());
  return landmarks;
}

BundleAdjustmentSummary LocalBundleAdjust(SlamState* state, const KeyframeOptions& options,
                                          const RectifiedIntrinsics& intrinsics,
                                          const BundleAdjustmentOptions& ba_options) {
  const int n = static_cast<int>(state->keyframes.size());
  if (n < 2) return {};
  std::vector<int> free, fixed;
  for (int k = std::max(0, n - options.window); k < n; ++k) {
    if (k > 0 && k >= n - options.free) {
      free.push_back(k);
    } else {
      fixed.push_back(k);
    }
  }
  BundleAdjustmentOptions local = ba_options;
  local.function_tolerance = options.local_ba_function_tolerance;
  return BundleAdjust(state, free, fixed, intrinsics, local);
}

}  // namespace visloc::mapping
