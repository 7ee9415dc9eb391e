// The localizer's decisions, one rule at a time (fix_policy.h): the jump gate, fixes held for
// confirmation, filter restarts and bridging. End-to-end behaviour on rendered and real
// sequences is tested in tests/.

#include "core/localization/fix_policy.h"

#include <gtest/gtest.h>

#include <cmath>

namespace visloc {
namespace {

using Action = FixDecision::Action;

Rigid3d Turned(double deg, const Eigen::Vector3d& t) {
  return Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(deg * M_PI / 180, Eigen::Vector3d::UnitY())),
                 t);
}

TEST(JumpGateTest, AFixWithinTheGateOfThePriorPassesAndTheGateWidensWithItsSigma) {
  LocalizerOptions options;  // 0.2 m, 10 deg, 3 sigma.
  const Rigid3d prior;
  EXPECT_TRUE(WithinJumpGate(Turned(0, {0.19, 0, 0}), prior, 0.0, options));
  EXPECT_FALSE(WithinJumpGate(Turned(0, {0.21, 0, 0}), prior, 0.0, options));
  // An uncertain prior (sigma 5 cm) admits 0.2 + 3 x 0.05 m.
  EXPECT_TRUE(WithinJumpGate(Turned(0, {0, 0.34, 0}), prior, 0.05, options));
  EXPECT_FALSE(WithinJumpGate(Turned(0, {0, 0.36, 0}), prior, 0.05, options));
  // Turning is gated alone: sigma does not widen it.
  EXPECT_TRUE(WithinJumpGate(Turned(9.5, {0, 0, 0}), prior, 0.05, options));
  EXPECT_FALSE(WithinJumpGate(Turned(10.5, {0, 0, 0}), prior, 0.05, options));
  // The gate's width is an option.
  options.jump_gate_sigmas = 1.0;
  EXPECT_FALSE(WithinJumpGate(Turned(0, {0, 0.34, 0}), prior, 0.05, options));
}

// A fix with enough support for a limited status, while the motion is known.
FixEvidence Fix(bool has_pose, bool within_gate, bool strong, bool strongly_supported = false) {
  FixEvidence e;
  e.has_pose = has_pose;
  e.within_gate = within_gate;
  e.limited_support = true;
  e.strong = strong;
  e.strongly_supported = strongly_supported;
  e.motion_known = true;
  return e;
}

FixEvidence Tracked(bool within_gate, bool strong) { return Fix(true, within_gate, strong); }

void ExpectTaken(const FixDecision& d, TrackingStatus status, FilterUpdate update) {
  EXPECT_EQ(d.action, Action::kTake);
  EXPECT_EQ(d.status, status);
  EXPECT_EQ(d.update, update);
}

TEST(FixPolicyTest, ATrackedFixWithinTheGateIsFusedAsTrackingOrLimited) {
  ExpectTaken(DecideTrackedFix(Tracked(true, true)), TrackingStatus::kTracking,
              FilterUpdate::kFuse);
  ExpectTaken(DecideTrackedFix(Tracked(true, false)), TrackingStatus::kLimited,
              FilterUpdate::kFuse);
  FixEvidence weak = Tracked(true, false);
  weak.limited_support = false;
  EXPECT_EQ(DecideTrackedFix(weak).action, Action::kReject);
}

// A strong fix whose covariance is mostly its points' (seen from where the map never looked) is
// fused, and reported limited: its sigma is honest, but the map cannot back it as it backs
// tracking.
TEST(FixPolicyTest, AStrongFixLeaningOnPointsTheMapKnowsPoorlyIsLimited) {
  FixEvidence leaning = Tracked(true, true);
  leaning.points_well_known = false;
  ExpectTaken(DecideTrackedFix(leaning), TrackingStatus::kLimited, FilterUpdate::kFuse);
}

// A jump: the next frame must confirm it, however strong, while the prior knew the motion.
TEST(FixPolicyTest, ATrackedFixBeyondTheGateIsHeldForConfirmation) {
  FixEvidence jump = Tracked(false, true);
  jump.strongly_supported = true;
  EXPECT_EQ(DecideTrackedFix(jump).action, Action::kHold);
  EXPECT_EQ(DecideTrackedFix(Tracked(false, false)).action, Action::kHold);
}

// A fix from a few points on one side of a half-covered image: within the jump gate, but far
// from the prediction for both uncertainties (the kidnap demo's frame 91 through the server:
// 31 inliers, 11 cm and 4 degrees off, squared Mahalanobis distance 56). It is held, not
// reported tracking.
TEST(FixPolicyTest, ATrackedFixThatDisagreesWithThePredictionIsHeldForConfirmation) {
  FixEvidence far = Tracked(true, true);
  far.agrees = false;
  EXPECT_EQ(DecideTrackedFix(far).action, Action::kHold);
  far.strong = false;
  EXPECT_EQ(DecideTrackedFix(far).action, Action::kHold);
}

// A car's first frames after a fix: no velocity yet, and it moved 0.8 m. A strongly supported
// fix restarts the filter keeping the motion from the last fix, so the next frame tracks.
TEST(FixPolicyTest, WithoutKnownMotionAStronglySupportedJumpRestartsKeepingTheMotion) {
  FixEvidence jump = Tracked(false, true);
  jump.strongly_supported = true;
  jump.motion_known = false;
  ExpectTaken(DecideTrackedFix(jump), TrackingStatus::kRelocalized,
              FilterUpdate::kRestartKeepingMotion);
  jump.strongly_supported = false;
  EXPECT_EQ(DecideTrackedFix(jump).action, Action::kHold);
}

TEST(FixPolicyTest, FromAHintWithNoPoseOnlyAStrongFixPlacesTheCamera) {
  FixEvidence hinted = Tracked(false, true);
  hinted.has_pose = false;
  ExpectTaken(DecideTrackedFix(hinted), TrackingStatus::kRelocalized, FilterUpdate::kRestart);
  hinted.strong = false;
  EXPECT_EQ(DecideTrackedFix(hinted).action, Action::kReject);  // Nothing to hold it against.
}

FixEvidence Relocalized(bool has_pose, bool within_gate, bool strongly_supported) {
  return Fix(has_pose, within_gate, /*strong=*/true, strongly_supported);
}

TEST(FixPolicyTest, ARelocalizationRestartsTheFilter) {
  // Where the prior expected it: taken, the filter restarted without velocity.
  ExpectTaken(DecideRelocalizedFix(Relocalized(true, true, false)), TrackingStatus::kRelocalized,
              FilterUpdate::kRestart);
  // Lost (no pose): a strongly supported fix is taken at once; a weak one waits for the next
  // frame (a look-alike place must not teleport the robot).
  ExpectTaken(DecideRelocalizedFix(Relocalized(false, false, true)), TrackingStatus::kRelocalized,
              FilterUpdate::kRestartKeepingMotion);
  EXPECT_EQ(DecideRelocalizedFix(Relocalized(false, false, false)).action, Action::kHold);
}

TEST(FixPolicyTest, AKidnappingIsHeldUntilConfirmedWhileThePriorKnowsTheMotion) {
  // The prior knows where the robot goes and the fix is elsewhere: held, however strong.
  EXPECT_EQ(DecideRelocalizedFix(Relocalized(true, false, true)).action, Action::kHold);
  // Nothing knows the motion (the frame after a relocalization): strong support decides.
  FixEvidence unknown = Relocalized(true, false, true);
  unknown.motion_known = false;
  EXPECT_EQ(DecideRelocalizedFix(unknown).action, Action::kTake);
}

TEST(FixPolicyTest, AHeldFixIsConfirmedOnlyByAStrongFixWhereTheMotionMovedIt) {
  ExpectTaken(DecideConfirmation(true, true), TrackingStatus::kRelocalized,
              FilterUpdate::kRestartKeepingMotion);
  EXPECT_EQ(DecideConfirmation(false, true).action, Action::kReject);
  EXPECT_EQ(DecideConfirmation(true, false).action, Action::kReject);
}

TEST(FixPolicyTest, BridgingNeedsAPoseSensorsTimeAndCertainty) {
  const MotionOptions options;  // 3 s, 0.5 m.
  BridgeEvidence e;
  e.has_pose = true;
  e.motion_from_sensors = true;
  e.since_fix_s = 1.0;
  e.position_sigma_m = 0.1;
  EXPECT_TRUE(ShouldBridge(e, options));
  BridgeEvidence vision_only = e;
  vision_only.motion_from_sensors = false;  // The constant-velocity guess alone is not bridged...
  EXPECT_FALSE(ShouldBridge(vision_only, options));
  MotionOptions compare = options;  // ...unless asked, for comparison.
  compare.bridge_with_constant_velocity = true;
  EXPECT_TRUE(ShouldBridge(vision_only, compare));
  BridgeEvidence too_long = e;
  too_long.since_fix_s = 3.5;
  EXPECT_FALSE(ShouldBridge(too_long, options));
  BridgeEvidence too_uncertain = e;
  too_uncertain.position_sigma_m = 0.6;
  EXPECT_FALSE(ShouldBridge(too_uncertain, options));
  BridgeEvidence no_pose = e;
  no_pose.has_pose = false;
  EXPECT_FALSE(ShouldBridge(no_pose, options));
}

}  // namespace
}  // namespace visloc
