#include "core/localization/localizability.h"

#include <cmath>

#include <gtest/gtest.h>

#include "core/map/synthetic_map.h"

namespace visloc {
namespace {

// A loop of keyframes of radius ~1.2 m, level cameras looking out, z up: its own site frame.
LocalizationMap LoopMap() {
  SyntheticMapOptions options;
  options.keyframes = 50;
  options.points = 8000;
  options.appearance = false;
  return LocalizationMap(MakeSyntheticMap(options));
}

TEST(LocalizabilityTest, ALevelCameraLooksAlongItsHeadingWithTheImageDownBelowIt) {
  const Rigid3d site_from_cam = LevelCameraPose({1, 2, 3}, M_PI / 2, 0.0);
  EXPECT_TRUE(
      (site_from_cam.rotation * Eigen::Vector3d::UnitZ()).isApprox(Eigen::Vector3d::UnitY()));
  EXPECT_TRUE(
      (site_from_cam.rotation * Eigen::Vector3d::UnitY()).isApprox(-Eigen::Vector3d::UnitZ()));
  EXPECT_TRUE(
      (site_from_cam.rotation * Eigen::Vector3d::UnitX()).isApprox(Eigen::Vector3d::UnitX()));
  // Pitched down 30 degrees: the optical axis drops by sin(30).
  const Rigid3d pitched = LevelCameraPose({0, 0, 0}, 0.0, M_PI / 6);
  EXPECT_NEAR((pitched.rotation * Eigen::Vector3d::UnitZ()).z(), -0.5, 1e-12);
}

TEST(LocalizabilityTest, AKeyframesOwnViewIsGoodAndAViewNoKeyframeHadIsPoor) {
  const LocalizationMap map = LoopMap();
  LocalizabilityOptions options;
  const LocalizabilityPredictor predictor(map, options);
  const Rigid3d& keyframe = map.map().keyframes[10].map_from_cam;
  const LocalizabilityEstimate at_keyframe = predictor.Predict(keyframe);
  EXPECT_GT(at_keyframe.expected_inliers, 100.0f);
  EXPECT_LT(at_keyframe.position_sigma_m, 0.05f);
  EXPECT_TRUE(at_keyframe.good);

  // Turned to face the loop's centre: no keyframe looked that way.
  const Rigid3d inward(keyframe.rotation * Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitY()),
                       keyframe.translation);
  const LocalizabilityEstimate turned = predictor.Predict(inward);
  EXPECT_LT(turned.expected_inliers, 0.1f * at_keyframe.expected_inliers);
  EXPECT_FALSE(turned.good);

  // Twenty metres away: nothing in reach, the pose unconstrained.
  const Rigid3d away(keyframe.rotation, keyframe.translation + Eigen::Vector3d(20, 0, 0));
  const LocalizabilityEstimate far = predictor.Predict(away);
  EXPECT_EQ(far.expected_inliers, 0.0f);
  EXPECT_TRUE(std::isinf(far.position_sigma_m));
}

TEST(LocalizabilityTest, APoseSigmaIsTheFisherInformationsOfItsExpectedInliers) {
  // Uncapped, the information is the expected inliers' sum: a quarter of the matchable share
  // is a quarter of the information and twice the sigma (the map's and rig's error left out;
  // the synthetic map knows no point uncertainty).
  const LocalizationMap map = LoopMap();
  LocalizabilityOptions options;
  options.max_inliers_per_100k_px = 0.0;
  options.tracker.map_error_px = 0.0;
  options.tracker.map_drift_fraction = 0.0;
  options.tracker.rig_floor_m = 0.0;
  options.tracker.rig_drift_fraction = 0.0;
  options.matchable_fraction = 0.8;
  const Rigid3d& keyframe = map.map().keyframes[3].map_from_cam;
  const LocalizabilityEstimate full = LocalizabilityPredictor(map, options).Predict(keyframe);
  options.matchable_fraction = 0.2;
  const LocalizabilityEstimate quarter = LocalizabilityPredictor(map, options).Predict(keyframe);
  EXPECT_NEAR(quarter.expected_inliers, full.expected_inliers / 4, 1e-3 * full.expected_inliers);
  EXPECT_NEAR(quarter.position_sigma_m, 2 * full.position_sigma_m, 1e-4 * full.position_sigma_m);
  EXPECT_EQ(quarter.visible_points, full.visible_points);
}

TEST(LocalizabilityTest, AFramesKeypointsBoundItsInliersWithoutTyingPosesBeyondThem) {
  // A pose at a keyframe and one a step back, both with more matchable points in view than the
  // frame has keypoints for: each expects fewer inliers than the cap, and the one seeing more
  // expects more. Clipped at the cap, the two tied, and a walk's poses beyond it ranked as one.
  const LocalizationMap map = LoopMap();
  LocalizabilityOptions options;
  options.max_inliers_per_100k_px = 100.0;  // 76.8 at 320x240.
  const LocalizabilityPredictor predictor(map, options);
  const Rigid3d& keyframe = map.map().keyframes[0].map_from_cam;
  const Rigid3d back(keyframe.rotation,
                     keyframe.translation - keyframe.rotation * Eigen::Vector3d(0, 0, 0.3));
  const LocalizabilityEstimate at = predictor.Predict(keyframe);
  const LocalizabilityEstimate behind = predictor.Predict(back);
  ASSERT_NE(at.visible_points, behind.visible_points);
  for (const LocalizabilityEstimate& e : {at, behind}) {
    const double matchable = e.visible_points * options.matchable_fraction;
    EXPECT_GT(matchable, 76.8);
    EXPECT_LT(e.expected_inliers, 76.8f);
    EXPECT_NEAR(e.expected_inliers, 76.8 * (1.0 - std::exp(-matchable / 76.8)), 1e-3);
  }
  EXPECT_EQ(at.expected_inliers < behind.expected_inliers,
            at.visible_points < behind.visible_points);
  // Few points in view: nearly all of their matchable share.
  options.max_inliers_per_100k_px = 1e5;
  const LocalizabilityEstimate uncrowded = LocalizabilityPredictor(map, options).Predict(keyframe);
  EXPECT_NEAR(uncrowded.expected_inliers, at.visible_points * options.matchable_fraction,
              0.01 * uncrowded.expected_inliers);
}

TEST(LocalizabilityTest, TheGridCoversTheKeyframesAndFindsThemGoodLookingOut) {
  const LocalizationMap map = LoopMap();
  LocalizabilityOptions options;
  options.cell_m = 0.25;
  options.headings = 8;
  LocalizabilityStats stats;
  const LocalizabilityGrid grid = ComputeLocalizability(map, Rigid3d::Identity(), options, &stats);
  EXPECT_EQ(stats.poses, grid.cells_x * grid.cells_y * 8);
  EXPECT_EQ(grid.estimates.size(), static_cast<size_t>(stats.poses));
  EXPECT_NEAR(grid.height_m, 0.0, 1e-9);  // The keyframes' height and pitch.
  EXPECT_NEAR(grid.pitch_deg, 0.0, 1e-9);
  EXPECT_GT(stats.good_poses, 0);

  // Every good pose outside the loop looks away from it or along it, never back into it (the
  // points lie 1-6 m in front of the keyframes, out of the loop).
  int counted = 0;
  for (int iy = 0; iy < grid.cells_y; ++iy) {
    for (int ix = 0; ix < grid.cells_x; ++ix) {
      for (int h = 0; h < grid.headings; ++h) {
        const Rigid3d site_from_cam = grid.SiteFromCam(ix, iy, h);
        const Eigen::Vector2d radial = site_from_cam.translation.head<2>();
        if (radial.norm() < 1.6 || !grid.at(ix, iy, h).good) continue;
        const Eigen::Vector3d forward = site_from_cam.rotation * Eigen::Vector3d::UnitZ();
        EXPECT_GT(forward.head<2>().dot(radial.normalized()), -0.5) << ix << " " << iy << " " << h;
        ++counted;
      }
    }
  }
  EXPECT_GT(counted, 50);

  int good_keyframes = 0;
  for (const Keyframe& keyframe : map.map().keyframes) {
    int ix = -1, iy = -1, heading = -1;
    ASSERT_TRUE(grid.Locate(keyframe.map_from_cam, &ix, &iy, &heading));
    good_keyframes += grid.at(ix, iy, heading).good;
    // The opposite heading, towards the loop's centre, is never good.
    EXPECT_FALSE(grid.at(ix, iy, (heading + 4) % 8).good);
  }
  // A cell's heading is up to 22.5 degrees and a cell's half-diagonal off the keyframe's.
  EXPECT_GE(good_keyframes, 45);
  // The grid's corners lie a margin beyond the loop: far from every keyframe's view.
  EXPECT_FALSE(grid.at(0, 0, 0).good);
}

TEST(LocalizabilityTest, AMapWithoutAKernelIsRefusedByName) {
  SyntheticMapOptions synthetic;
  synthetic.keyframes = 10;
  synthetic.points = 100;
  synthetic.appearance = false;
  Map raw = MakeSyntheticMap(synthetic);
  raw.kernel = {};
  const LocalizationMap map(std::move(raw));
  try {
    LocalizabilityPredictor predictor(map, {});
    FAIL() << "a map without a kernel was accepted";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("visibility kernel"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace visloc
