#include "core/localization/fix_policy.h"

namespace visloc {

const char* TrackingStatusName(TrackingStatus status) {
  switch (status) {
    case TrackingStatus::kInitializing:
      return "initializing";
    case TrackingStatus::kTracking:
      return "tracking";
    case TrackingStatus::kLimited:
      return "limited";
    case TrackingStatus::kRelocalized:
      return "relocalized";
    case TrackingStatus::kLost:
      return "lost";
  }
  return "?";
}

bool WithinJumpGate(const Rigid3d& found, const Rigid3d& expected, double sigma_m,
                    const LocalizerOptions& options) {
  const double moved_m = (found.translation - expected.translation).norm();
  const double turned_deg = RotationAngleDeg(expected.rotation.inverse() * found.rotation);
  return moved_m <= options.max_jump_m + options.jump_gate_sigmas * sigma_m &&
         turned_deg <= options.max_jump_deg;
}

namespace {

FixDecision Take(TrackingStatus status, FilterUpdate update) {
  return {FixDecision::Action::kTake, status, update};
}

constexpr FixDecision kReject{};
constexpr FixDecision kHold{FixDecision::Action::kHold, TrackingStatus::kInitializing,
                            FilterUpdate::kFuse};

}  // namespace

FixDecision DecideTrackedFix(const FixEvidence& e) {
  if (!e.limited_support) return kReject;
  // From a hint, with nothing to fuse with: only a strong fix places the camera.
  if (!e.has_pose) {
    return e.strong ? Take(TrackingStatus::kRelocalized, FilterUpdate::kRestart) : kReject;
  }
  if (e.within_gate && e.agrees) {
    return Take(e.strong && e.points_well_known ? TrackingStatus::kTracking
                                                : TrackingStatus::kLimited,
                FilterUpdate::kFuse);
  }
  // The prior knew no velocity (the first frames after a fix) and the camera moved further than
  // a walking robot would: a car's 0.8 m a frame. A fix this well supported, found by tracking
  // from the last pose, is taken at once, as a strongly supported relocalization is: reported
  // relocalized (the pose jumped from the prediction), its motion from the last fix the velocity.
  if (!e.motion_known && e.strong && e.strongly_supported) {
    return Take(TrackingStatus::kRelocalized, FilterUpdate::kRestartKeepingMotion);
  }
  return kHold;
}

FixDecision DecideRelocalizedFix(const FixEvidence& e) {
  const bool consistent = e.has_pose && e.within_gate;
  // Without a velocity (the frame after a relocalization) the prior cannot tell where a fast
  // camera went, so a strongly supported fix is taken as it would be with no prior at all.
  if (consistent || (e.strongly_supported && (!e.has_pose || !e.motion_known))) {
    return Take(TrackingStatus::kRelocalized,
                consistent ? FilterUpdate::kRestart : FilterUpdate::kRestartKeepingMotion);
  }
  return kHold;
}

FixDecision DecideConfirmation(bool strong, bool within_gate) {
  // The confirmed fix counts as the last one: the motion from it to this frame is the velocity,
  // so a camera that moves faster than the prior allows (a car's 2 m between frames) tracks the
  // next frame instead of being lost and relocalized again.
  if (strong && within_gate) {
    return Take(TrackingStatus::kRelocalized, FilterUpdate::kRestartKeepingMotion);
  }
  return kReject;
}

bool ShouldBridge(const BridgeEvidence& e, const MotionOptions& options) {
  return e.has_pose && (e.motion_from_sensors || options.bridge_with_constant_velocity) &&
         e.since_fix_s <= options.max_bridge_s && e.position_sigma_m <= options.max_bridge_sigma_m;
}

}  // namespace visloc
