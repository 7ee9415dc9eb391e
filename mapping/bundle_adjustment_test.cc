#include "mapping/bundle_adjustment.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "core/util/random.h"
#include "mapping/keyframes.h"

namespace visloc::mapping {
namespace {

const RectifiedIntrinsics kRig{500.0, 320.0, 240.0, 0.2};

// Keyframe k's observation of `point_in_world`, with keypoint and disparity noise; left-only
// (no right match) when asked.
void Observe(const Eigen::Vector3d& point_in_world, int l, int k, bool left_only, Rng* rng,
             SlamState* state) {
  SlamKeyframe& keyframe = state->keyframes[k];
  const Eigen::Vector3d p = keyframe.cam_from_world * point_in_world;
  keyframe.left_rect.emplace_back(kRig.f * p.x() / p.z() + kRig.cx + rng->Normal(0, 0.3),
                                  kRig.f * p.y() / p.z() + kRig.cy + rng->Normal(0, 0.3));
  const double disparity = kRig.f * kRig.baseline_m / p.z() + rng->Normal(0, 0.05);
  keyframe.right_x_rect.push_back(left_only ? std::numeric_limits<double>::quiet_NaN()
                                            : keyframe.left_rect.back().x() - disparity);
  keyframe.landmark.push_back(-1);
  state->Observe(l, k, static_cast<int>(keyframe.landmark.size()) - 1);
}

// Four keyframes 0.3 m apart (the poses after the first off by a centimetre), 80 points seen
// by all of them, and 30 seen by one of the last three each (a fifth of those left-only), every
// point 3% off in depth.
SlamState WithLandmarksSeenOnce() {
  Rng rng(5);
  SlamState state;
  for (int k = 0; k < 4; ++k) {
    SlamKeyframe keyframe;
    keyframe.cam_from_world =
        Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.01 * (k > 0), 0.0, -0.3 * k));
    state.keyframes.push_back(keyframe);
  }
  for (int l = 0; l < 110; ++l) {
    const Eigen::Vector3d truth(rng.Uniform(-2.0, 2.0), rng.Uniform(-1.5, 1.5),
                                rng.Uniform(4.0, 12.0));
    state.landmarks.emplace_back();
    state.landmarks.back().position_in_world = truth * (1.0 + rng.Normal(0, 0.03));
    if (l < 80) {
      for (int k = 0; k < 4; ++k) Observe(truth, l, k, false, &rng, &state);
    } else {
      Observe(truth, l, 1 + l % 3, l % 5 == 0, &rng, &state);
    }
  }
  return state;
}

// The same state without the landmarks seen once.
SlamState WithoutThem(SlamState state) {
  for (int l = 80; l < 110; ++l) {
    for (const auto& [k, i] : state.landmarks[l].observations) state.keyframes[k].landmark[i] = -1;
    state.landmarks[l].observations.clear();
    state.landmarks[l].culled = true;
  }
  return state;
}

// A landmark one keyframe sees fits that keyframe's observation whatever the poses are, so it
// must change nothing else: the adjustment comes out as without it, to the bit (the solver
// does not even see it), and it ends on its observation, as the solver would have taken it.
TEST(BundleAdjustmentTest, ALandmarkSeenOnceChangesNothingAndEndsOnItsObservation) {
  for (bool estimate_correction : {false, true}) {
    SCOPED_TRACE(estimate_correction ? "estimating the correction" : "poses and points");
    BundleAdjustmentOptions options;
    options.max_iterations = 30;
    options.estimate_disparity_correction = estimate_correction;
    SlamState with = WithLandmarksSeenOnce();
    SlamState without = WithoutThem(with);
    const BundleAdjustmentSummary a = BundleAdjust(&with, {1, 2, 3}, {0}, kRig, options);
    const BundleAdjustmentSummary b = BundleAdjust(&without, {1, 2, 3}, {0}, kRig, options);
    EXPECT_EQ(a.residual_blocks, 4 * 80);
    EXPECT_EQ(a.residual_blocks, b.residual_blocks);
    EXPECT_EQ(a.correction_change.offset_px, b.correction_change.offset_px);
    EXPECT_EQ(a.correction_change.yaw_rad, b.correction_change.yaw_rad);
    for (int k = 0; k < 4; ++k) {
      EXPECT_EQ(with.keyframes[k].cam_from_world.translation,
                without.keyframes[k].cam_from_world.translation);
      EXPECT_EQ(with.keyframes[k].cam_from_world.rotation.coeffs(),
                without.keyframes[k].cam_from_world.rotation.coeffs());
    }
    for (int l = 0; l < 80; ++l) {
      EXPECT_EQ(with.landmarks[l].position_in_world, without.landmarks[l].position_in_world);
    }
    // The moved keyframes moved the landmarks they alone see with them, onto their observations.
    EXPECT_GT(
        (with.keyframes[1].cam_from_world.translation - Eigen::Vector3d(0.01, 0, -0.3)).norm(),
        1e-3);
    for (int l = 80; l < 110; ++l) {
      ASSERT_EQ(with.landmarks[l].observations.size(), 1u) << "landmark " << l << " was culled";
      const auto [k, i] = with.landmarks[l].observations[0];
      const ObservationError e = ObservationErrors(with, l, k, i, kRig);
      EXPECT_LT(e.left_px, 1e-9) << "landmark " << l;
      if (l % 5 != 0) {
        EXPECT_LT(e.disparity_px, 1e-9) << "landmark " << l;
      }
    }
  }
}

// The local adjustment stops at its own, looser tolerance: later adjustments move its keyframes
// again, so it need not polish them. It takes fewer iterations and lands within 2% of the
// full adjustment's move (here 5 mm) of where that ends; the global adjustment keeps the
// solver's default tolerance.
TEST(BundleAdjustmentTest, TheLocalAdjustmentStopsAtItsLooserToleranceNearWhereTheFullOneEnds) {
  KeyframeOptions window;
  window.window = 4;
  window.free = 3;
  BundleAdjustmentOptions options;
  options.max_iterations = 30;
  ASSERT_EQ(options.function_tolerance, 1e-6);
  SlamState full = WithoutThem(WithLandmarksSeenOnce());
  SlamState local = full;
  const BundleAdjustmentSummary a = BundleAdjust(&full, {1, 2, 3}, {0}, kRig, options);
  const BundleAdjustmentSummary b = LocalBundleAdjust(&local, window, kRig, options);
  EXPECT_EQ(b.keyframes, 4);
  EXPECT_LT(b.iterations, a.iterations);
  for (int k = 1; k < 4; ++k) {
    const Eigen::Vector3d start(0.01, 0.0, -0.3 * k);
    const double moved_m = (full.keyframes[k].cam_from_world.translation - start).norm();
    const double apart_m = (local.keyframes[k].cam_from_world.translation -
                            full.keyframes[k].cam_from_world.translation)
                               .norm();
    EXPECT_GT(moved_m, 3e-3) << "keyframe " << k;
    EXPECT_LT(apart_m, 0.02 * moved_m) << "keyframe " << k;
  }
  window.local_ba_function_tolerance = 1e-6;  // As tight as the full one: the same adjustment.
  SlamState tight = WithoutThem(WithLandmarksSeenOnce());
  EXPECT_EQ(LocalBundleAdjust(&tight, window, kRig, options).iterations, a.iterations);
  EXPECT_EQ(tight.keyframes[3].cam_from_world.translation,
            full.keyframes[3].cam_from_world.translation);
}

}  // namespace
}  // namespace visloc::mapping
