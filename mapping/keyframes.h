#pragma once
// Keyframing (seed paper 000, sec. 3): when a tracked frame becomes a keyframe, what it adds to
// the map (its untracked stereo points become landmarks), and the local bundle adjustment over
// the latest keyframes that follows.

#include <cstdint>
#include <vector>

#include "mapping/bundle_adjustment.h"
#include "mapping/landmark_matching.h"
#include "mapping/slam_state.h"
#include "mapping/stereo_frame.h"

namespace visloc::mapping {

struct KeyframeOptions {
  // A frame becomes a keyframe when the camera moved or turned this far since the last keyframe
  // (paper: 0.15 m, 5 deg), or tracked fewer landmarks than `min_tracked` (the view changed).
  double translation_m = 0.15;
  double rotation_deg = 5.0;
  int min_tracked = 60;
  // Local bundle adjustment: the last `window` keyframes (N_k), of which the last `free` (n_k)
  // are optimized and the rest held fixed (paper: 10 and 3). Tracking matches the landmarks of
  // the same window.
  int window = 10;
  int free = 3;
  // The local adjustment stops once an iteration lowers its cost by less than this fraction
  // (Ceres's function tolerance, 1e-6 by default). Each keyframe is adjusted again by the next
  // `free` - 1 local adjustments and by the global one at the end, so polishing a window to the
  // last digits is work the next adjustment redoes: at 1e-3 a KITTI 01 build's local adjustments
  // take 35-40% less time, and the maps of the real recordings are as accurate (MH_01 0.28 cm
  // median keyframe error either way; KITTI 01 1.19% of the distance against 1.21%).
  double local_ba_function_tolerance = 1e-3;
  void Check() const;
};

bool NeedsKeyframe(const KeyframeOptions& options, const Rigid3d& cam_from_world,
                   const Rigid3d& keyframe_cam_from_world, int tracked);

// Appends `frame` as a keyframe at `cam_from_world`: the tracked matches observe their
// landmarks, and every other keypoint with a stereo point starts a new landmark.
void AddKeyframe(SlamState* state, int64_t timestamp_ns, StereoFrame&& frame,
                 const Rigid3d& cam_from_world, const std::vector<LandmarkMatch>& tracked);

// The landmarks (not culled) observed by the last `window` keyframes, ascending.
std::vector<int> RecentLandmarks(const SlamState& state, int window);

// Bundle adjustment of the last options.free keyframes (never the first keyframe, which fixes
// the world frame), with the rest of the window held fixed, to options.local_ba_function_tolerance.
BundleAdjustmentSummary LocalBundleAdjust(SlamState* state, const KeyframeOptions& options,
                                          const RectifiedIntrinsics& intrinsics,
                                          const BundleAdjustmentOptions& ba_options);

double AngleBetweenDeg(const Rigid3d& a, const Rigid3d& b);
// The camera centre of a cam_from_world pose.
inline Eigen::Vector3d CameraCenter(const Rigid3d& cam_from_world) {
  return cam_from_world.Inverse().translation;
}

}  // namespace visloc::mapping
