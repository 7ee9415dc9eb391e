#pragma once
// Which visual fixes a session takes, and how they enter its motion filter: the decisions of
// Localizer::Process as pure functions of what it knows when a fix arrives (no images, no map),
// so each rule is tested alone.
//
//   tracked from the prior    within the jump gate and agreeing with the prediction: tracking
//                             (strong, from points the map knows well from here) or limited;
//                             else held for the next frame to confirm,
//                             unless the prior knew no motion and the fix is strongly supported
//                             (a car's first frames);
//                             with no prior pose: a strong fix is a relocalization.
//   relocalized               within the gate of the prior, or strongly supported while nothing
//                             (no pose, no motion) says where the camera went: taken; else held.
//   held, then re-tracked     strong and where the motion moved it: a relocalization.
//   no fix                    bridged by the motion prediction while odometry or gyro carry it,
//                             for a while; else lost.

#include "core/geometry/rigid3.h"
#include "core/localization/localizer_options.h"

namespace visloc {

enum class TrackingStatus { kInitializing, kTracking, kLimited, kRelocalized, kLost };
const char* TrackingStatusName(TrackingStatus status);

// How a taken fix enters the filter: fused with the prediction (the velocity follows from the
// previous fix), restarting it with no velocity (a relocalization: the pose may have jumped
// anywhere), or restarting it with the velocity from the previous fix (a motion the prediction
// could not foresee, tracked from the previous pose).
enum class FilterUpdate { kFuse, kRestart, kRestartKeepingMotion };

// The jump gate: `found` moved at most max_jump_m + jump_gate_sigmas * `sigma_m` (the prior's
// position uncertainty) and turned at most max_jump_deg from `expected`.
bool WithinJumpGate(const Rigid3d& found, const Rigid3d& expected, double sigma_m,
                    const LocalizerOptions& options);

// What the session knows when it weighs a fix.
struct FixEvidence {
  bool has_pose = false;            // The filter holds a pose (tracking, limited or bridging).
  bool within_gate = false;         // Of that pose (false without one).
  bool agrees = true;               // With the filter's prediction (max_innovation_chi2).
  bool limited_support = false;     // min_limited_inliers.
  bool strong = false;              // min_tracking_inliers and min_tracking_inlier_ratio.
  // The fix's uncertainty is mostly its own, not its points' (max_tracking_point_variance_ratio).
  bool points_well_known = true;
  bool strongly_supported = false;  // relocalization.strong_inliers.
  bool motion_known = false;        // A velocity from recent fixes, or odometry / gyro now.
};

struct FixDecision {
  enum class Action { kReject, kTake, kHold };
  Action action = Action::kReject;
  TrackingStatus status = TrackingStatus::kInitializing;  // When taken.
  FilterUpdate update = FilterUpdate::kFuse;              // When taken.

  bool taken() const { return action == Action::kTake; }
  bool held() const { return action == Action::kHold; }
};

// A fix found by guided tracking from the filter's pose (or, with no pose, from a hint).
FixDecision DecideTrackedFix(const FixEvidence& evidence);
// A fix found by relocalization.
FixDecision DecideRelocalizedFix(const FixEvidence& evidence);
// A held fix, re-tracked this frame from where the motion moved it; `within_gate` of that pose.
FixDecision DecideConfirmation(bool strong, bool within_gate);

// Whether a frame without a visual fix gets the motion prediction as its pose (limited).
struct BridgeEvidence {
  bool has_pose = false;
  bool motion_from_sensors = false;  // Odometry or gyro this frame.
  double since_fix_s = 0.0;
  double position_sigma_m = 0.0;  // The filter's, after the prediction.
};
bool ShouldBridge(const BridgeEvidence& evidence, const MotionOptions& options);

}  // namespace visloc
