#pragma once
// Bundle adjustment over a SlamState with Ceres (seed paper 000, sec. 3.3): the poses of the
// `free` keyframes and the landmarks they observe are optimized against every observation of
// those landmarks by free and `fixed` keyframes, with a Huber loss. Local BA passes the last
// n_k keyframes as free and the rest of the window as fixed; global BA frees all but the first.

#include <vector>

#include "mapping/reprojection_cost.h"
#include "mapping/slam_state.h"

namespace visloc::mapping {

struct BundleAdjustmentOptions {
  double huber_px = 2.0;
  double disparity_weight = 8.0;  // sigma_keypoint / sigma_disparity (see reprojection_cost.h).
  int max_iterations = 15;
  // The solver stops when an iteration lowers the cost by less than this fraction of it (Ceres's
  // function tolerance; its default).
  double function_tolerance = 1e-6;
  double cull_error_px = 3.0;  // Afterwards: drop observations above this; paper: 3 px.
  // Also estimate a change of the rig's disparity correction (core/camera/disparity_correction.h)
  // with the poses and points, under a zero-mean prior of these sigmas (what keeps it where it is
  // when the motion cannot tell: a camera standing still). The change is applied to every
  // keyframe's stereo matches, since it belongs to the rig.
  bool estimate_disparity_correction = false;
  double correction_offset_sigma_px = 2.0;
  double correction_yaw_sigma_deg = 0.3;
};

struct BundleAdjustmentSummary {
  int keyframes = 0;
  int landmarks = 0;
  int residual_blocks = 0;
  int iterations = 0;
  double initial_rmse_px = 0.0;  // Left image reprojection error.
  double final_rmse_px = 0.0;
  int culled_observations = 0;
  DisparityCorrection correction_change;  // Estimated and applied (when asked for).
  double time_ms = 0.0;
};

BundleAdjustmentSummary BundleAdjust(SlamState* state, const std::vector<int>& free_keyframes,
                                     const std::vector<int>& fixed_keyframes,
                                     const RectifiedIntrinsics& intrinsics,
                                     const BundleAdjustmentOptions& options);

// Takes `change` off every stereo match of the state's keyframes (their right image columns).
void ApplyDisparityCorrection(const DisparityCorrection& change,
                              const RectifiedIntrinsics& intrinsics, SlamState* state);

struct ObservationError {
  double left_px = 0.0;       // Reprojection error in the (rectified) left image.
  double disparity_px = 0.0;  // |predicted - measured disparity|; NaN for a mono observation.
};

// Errors of landmark `l` as observed by keyframe `k`'s keypoint `i`.
ObservationError ObservationErrors(const SlamState& state, int l, int k, int i,
                                   const RectifiedIntrinsics& intrinsics);

}  // namespace visloc::mapping
