#include <gtest/gtest.h>

#include "core/estimators/p3p.h"
#include "core/estimators/pnp_ransac.h"
#include "core/estimators/pose_refinement.h"
#include "core/util/random.h"

namespace visloc {
namespace {

constexpr double kFocal = 160.0;

// Points 1-6 m in front of a camera at `cam_from_world`, observed with pixel noise and a share
// of gross outliers.
std::vector<PoseObservation> MakeObservations(const Rigid3d& cam_from_world, int count,
                                              double noise_px, double outlier_share, bool stereo,
                                              Rng& rng) {
  std::vector<PoseObservation> observations;
  const Rigid3d world_from_cam = cam_from_world.Inverse();
  for (int i = 0; i < count; ++i) {
    const Eigen::Vector3d in_cam(rng.Uniform(-1, 1), rng.Uniform(-0.75, 0.75), 1.0);
    const Eigen::Vector3d p = in_cam * rng.Uniform(1.0, 6.0);
    PoseObservation o;
    o.point_in_world = world_from_cam * p;
    o.normalized =
        p.head<2>() / p.z() + Eigen::Vector2d(rng.Normal(), rng.Normal()) * noise_px / kFocal;
    if (stereo) {
      o.has_right = true;
      o.right_x_normalized = (p.x() - 0.144) / p.z() + rng.Normal() * noise_px / kFocal;
    }
    if (rng.Uniform01() < outlier_share)
      o.normalized += Eigen::Vector2d(rng.Uniform(-0.5, 0.5), rng.Uniform(-0.5, 0.5));
    observations.push_back(o);
  }
  return observations;
}

const Rigid3d kTruth(RotationFromRollPitchYaw(0.1, -0.3, 1.2), Eigen::Vector3d(0.4, -0.2, 1.5));

TEST(P3PTest, ExactCorrespondencesGiveTheTruthAmongTheSolutions) {
  Rng rng(1);
  const auto observations = MakeObservations(kTruth, 3, 0.0, 0.0, false, rng);
  const auto solutions = SolveP3P(
      {observations[0].point_in_world, observations[1].point_in_world,
       observations[2].point_in_world},
      {observations[0].normalized, observations[1].normalized, observations[2].normalized});
  ASSERT_FALSE(solutions.empty());
  bool found = false;
  for (const Rigid3d& s : solutions) found |= ApproxEqual(s, kTruth, 1e-6, 1e-4);
  EXPECT_TRUE(found);
}

TEST(P3PTest, QuarticRootsAreFoundAndPolished) {
  // (x - 1)(x + 2)(x - 0.5)(x - 3) = x^4 - 2.5 x^3 - 4 x^2 + 8.5 x - 3, scaled by 2.
  std::array<double, 4> roots;
  ASSERT_EQ(SolveQuartic({2, -5, -8, 17, -6}, &roots), 4);
  std::sort(roots.begin(), roots.end());
  EXPECT_NEAR(roots[0], -2.0, 1e-12);
  EXPECT_NEAR(roots[1], 0.5, 1e-12);
  EXPECT_NEAR(roots[2], 1.0, 1e-12);
  EXPECT_NEAR(roots[3], 3.0, 1e-12);
  // (x^2 + 1)(x - 2)(x + 1) = x^4 - x^3 - x^2 - x - 2: two real roots.
  ASSERT_EQ(SolveQuartic({1, -1, -1, -1, -2}, &roots), 2);
  EXPECT_NEAR(std::max(roots[0], roots[1]), 2.0, 1e-12);
  EXPECT_NEAR(std::min(roots[0], roots[1]), -1.0, 1e-12);
  // Biquadratic (x^2 - 4)(x^2 - 9): the resolvent's root is 0.
  ASSERT_EQ(SolveQuartic({1, 0, -13, 0, 36}, &roots), 4);
  std::sort(roots.begin(), roots.end());
  EXPECT_NEAR(roots[0], -3.0, 1e-12);
  EXPECT_NEAR(roots[3], 3.0, 1e-12);
  // Not a quartic: no roots rather than a division by zero.
  EXPECT_EQ(SolveQuartic({0, 1, -3, 0, 2}, &roots), 0);
}

// Random poses and random point triplets in front of the camera: the true pose is always
// among the solutions, and every solution reprojects the three points exactly.
TEST(P3PTest, RandomConfigurationsRecoverTheTruth) {
  Rng rng(11);
  int found = 0, trials = 0;
  for (int trial = 0; trial < 500; ++trial) {
    const Rigid3d truth(
        RotationFromRollPitchYaw(rng.Uniform(-3, 3), rng.Uniform(-1.5, 1.5), rng.Uniform(-3, 3)),
        Eigen::Vector3d(rng.Uniform(-2, 2), rng.Uniform(-2, 2), rng.Uniform(-2, 2)));
    std::array<Eigen::Vector3d, 3> points;
    std::array<Eigen::Vector2d, 3> bearings;
    for (int i = 0; i < 3; ++i) {
      const Eigen::Vector3d in_cam(rng.Uniform(-1, 1), rng.Uniform(-0.8, 0.8), rng.Uniform(0.5, 6));
      points[i] = truth.Inverse() * in_cam;
      bearings[i] = in_cam.head<2>() / in_cam.z();
    }
    ++trials;
    const std::vector<Rigid3d> solutions = SolveP3P(points, bearings);
    bool has_truth = false;
    for (const Rigid3d& s : solutions) {
      has_truth |= ApproxEqual(s, truth, 1e-6, 1e-4);
      for (int i = 0; i < 3; ++i) {
        const Eigen::Vector3d p = s * points[i];
        EXPECT_GT(p.z(), 0);
        EXPECT_LT((p.head<2>() / p.z() - bearings[i]).norm(), 1e-6);
      }
    }
    found += has_truth;
  }
  // Near-degenerate triplets (almost collinear, or on the danger cylinder) may lose the
  // truth to rounding; RANSAC draws another. Anything more is a solver bug.
  EXPECT_GE(found, trials - 3);
}

TEST(P3PTest, CollinearPointsGiveNoSolution) {
  const std::array<Eigen::Vector3d, 3> points = {Eigen::Vector3d(0, 0, 2), Eigen::Vector3d(1, 0, 2),
                                                 Eigen::Vector3d(2, 0, 2)};
  const std::array<Eigen::Vector2d, 3> bearings = {Eigen::Vector2d(0, 0), Eigen::Vector2d(0.5, 0),
                                                   Eigen::Vector2d(1, 0)};
  EXPECT_TRUE(SolveP3P(points, bearings).empty());
}

// 150 points seen by one camera at kTruth with 0.5 px noise, and a start a few centimetres and
// degrees from it.
std::vector<PoseObservation> MonocularObservations() {
  Rng rng(2);
  return MakeObservations(kTruth, 150, 0.5, 0.0, false, rng);
}
Rigid3d PerturbedStart() {
  return Rigid3d(RotationFromRollPitchYaw(0.02, -0.01, 0.03), Eigen::Vector3d(0.05, -0.04, 0.1)) *
         kTruth;
}

TEST(PoseRefinementTest, ConvergesFromAPerturbedPoseAndGivesACovariance) {
  const auto observations = MonocularObservations();
  const Rigid3d start = PerturbedStart();
  PoseRefineOptions options;
  options.focal_px = kFocal;
  PoseRefineStats stats;
  Eigen::Matrix<double, 6, 6> covariance;
  const Rigid3d refined = RefinePose(start, observations, options, &stats, &covariance);
  EXPECT_TRUE(ApproxEqual(refined, kTruth, 0.01, 0.1));
  EXPECT_GT(stats.initial_rmse_px, 5.0);
  EXPECT_NEAR(stats.final_rmse_px, 0.5, 0.1);
  EXPECT_TRUE(covariance.allFinite());
  EXPECT_GT(covariance.diagonal().minCoeff(), 0.0);
  // The translation standard deviation for 150 points at 0.5 px is millimetres, not metres.
  EXPECT_LT(std::sqrt(covariance(2, 2)), 0.05);
}

// Restarted at its own optimum, the refinement's next step is far below any measurable motion;
// it stops there instead of shrinking that step through every remaining iteration (a
// tracking frame's second refinement pass starts at the first one's optimum).
TEST(PoseRefinementTest, StopsWhenTheStepIsBelowMeasurableMotion) {
  const auto observations = MonocularObservations();
  const Rigid3d start = PerturbedStart();
  PoseRefineOptions options;
  options.focal_px = kFocal;
  PoseRefineStats first, again;
  const Rigid3d optimum = RefinePose(start, observations, options, &first);
  ASSERT_TRUE(first.converged);
  EXPECT_LT(first.iterations, options.max_iterations);
  const Rigid3d restarted = RefinePose(optimum, observations, options, &again);
  EXPECT_TRUE(again.converged);
  EXPECT_EQ(again.iterations, 1);
  EXPECT_TRUE(ApproxEqual(restarted, optimum, 1e-8, 1e-8));
}

TEST(PoseRefinementTest, StereoResidualsTightenDepth) {
  Rng rng_mono(3), rng_stereo(3);
  const auto mono = MakeObservations(kTruth, 40, 0.5, 0.0, false, rng_mono);
  const auto stereo = MakeObservations(kTruth, 40, 0.5, 0.0, true, rng_stereo);
  PoseRefineOptions options;
  options.focal_px = kFocal;
  options.baseline_m = 0.144;
  Eigen::Matrix<double, 6, 6> mono_cov, stereo_cov;
  RefinePose(kTruth, mono, options, nullptr, &mono_cov);
  RefinePose(kTruth, stereo, options, nullptr, &stereo_cov);
  EXPECT_LT(stereo_cov.trace(), mono_cov.trace());
}

// The cost the header documents, in pixels: Huber on the left image's reprojection errors and on
// the weighted disparity error w (f B / z - (x_left - x_right)).
double DocumentedStereoCost(const Rigid3d& cam_from_world,
                            const std::vector<PoseObservation>& observations,
                            const PoseRefineOptions& options) {
  const auto huber = [&](double r) {
    const double a = std::abs(r), h = options.huber_px;
    return a <= h ? r * r : h * (2 * a - h);
  };
  double cost = 0.0;
  for (const PoseObservation& o : observations) {
    const Eigen::Vector3d p = cam_from_world * o.point_in_world;
    const double f = options.focal_px;
    cost += huber(f * (p.x() / p.z() - o.normalized.x()));
    cost += huber(f * (p.y() / p.z() - o.normalized.y()));
    const double measured_disparity = o.normalized.x() - o.right_x_normalized;
    cost += huber(f * options.disparity_weight * (options.baseline_m / p.z() - measured_disparity));
  }
  return cost;
}

TEST(PoseRefinementTest, StereoRefinementMinimizesTheWeightedDisparityCost) {
  Rng rng(4);
  const auto observations = MakeObservations(kTruth, 60, 1.0, 0.0, true, rng);
  PoseRefineOptions options;
  options.focal_px = kFocal;
  options.baseline_m = 0.144;
  options.disparity_weight = 8.0;
  const Rigid3d refined = RefinePose(kTruth, observations, options);
  const double at_refined = DocumentedStereoCost(refined, observations, options);
  // No small move of the pose (0.1 mm, 0.1 mrad, left perturbation) lowers the cost: the
  // refinement found a minimum of the documented cost, not of another one.
  for (int axis = 0; axis < 6; ++axis) {
    for (const double step : {-1e-4, 1e-4}) {
      Eigen::Vector3d translation = Eigen::Vector3d::Zero();
      Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
      if (axis < 3) {
        translation(axis) = step;
      } else {
        rotation = Eigen::AngleAxisd(step, Eigen::Vector3d::Unit(axis - 3));
      }
      const Rigid3d moved(rotation * refined.rotation,
                          rotation * refined.translation + translation);
      EXPECT_GE(DocumentedStereoCost(moved, observations, options), at_refined * (1 - 1e-9))
          << "axis " << axis << " step " << step;
    }
  }
}

TEST(PnpRansacTest, FindsThePoseAmongOutliers) {
  Rng rng(4);
  const auto observations = MakeObservations(kTruth, 200, 0.5, 0.4, false, rng);
  PnpRansacOptions options;
  options.refine.focal_px = kFocal;
  const PnpResult result = SolvePnpRansac(observations, options);
  ASSERT_TRUE(result.success);
  EXPECT_TRUE(ApproxEqual(result.cam_from_world, kTruth, 0.01, 0.1));
  EXPECT_NEAR(result.stats.inlier_ratio, 0.6, 0.08);
  EXPECT_LT(result.stats.iterations, 100);
  // Deterministic given the seed.
  EXPECT_TRUE(ApproxEqual(SolvePnpRansac(observations, options).cam_from_world,
                          result.cam_from_world, 0, 0));
}

TEST(PnpRansacTest, FailsCleanlyWithoutEnoughSupport) {
  Rng rng(5);
  PnpRansacOptions options;
  options.refine.focal_px = kFocal;
  EXPECT_FALSE(SolvePnpRansac(MakeObservations(kTruth, 3, 0.0, 0.0, false, rng), options).success);
  EXPECT_FALSE(
      SolvePnpRansac(MakeObservations(kTruth, 100, 0.5, 1.0, false, rng), options).success);
}

// A front-back rig: the reference camera, and a second one 0.1 m behind it looking backwards
// (turned half a turn about its y axis), each seeing its own points.
std::vector<Rigid3d> FrontBackCamFromRef() {
  return {Rigid3d(), Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitY())),
                             Eigen::Vector3d(0.0, 0.0, -0.1))};
}

RigObservations FrontBackObservations(int front_count, int back_count, double outlier_share,
                                      Rng& rng) {
  RigObservations rig;
  rig.cam_from_ref = FrontBackCamFromRef();
  rig.per_camera = {
      MakeObservations(kTruth, front_count, 0.5, outlier_share, false, rng),
      MakeObservations(rig.cam_from_ref[1] * kTruth, back_count, 0.5, outlier_share, false, rng)};
  return rig;
}

// SolveRigPnpRansac on `rig` at kFocal, expected to find kTruth.
RigPnpResult SolveExpectingTheTruth(const RigObservations& rig) {
  PnpRansacOptions options;
  options.refine.focal_px = kFocal;
  const RigPnpResult result = SolveRigPnpRansac(rig, options);
  EXPECT_TRUE(result.success);
  EXPECT_TRUE(ApproxEqual(result.ref_from_world, kTruth, 0.01, 0.3));
  return result;
}

TEST(RigPnpTest, FindsTheRigsPoseFromBothCamerasAmongOutliers) {
  Rng rng(21);
  const RigObservations rig = FrontBackObservations(120, 120, 0.3, rng);
  const RigPnpResult result = SolveExpectingTheTruth(rig);
  ASSERT_EQ(result.camera_inliers.size(), 2u);
  // About 70% of each camera's points are inliers: both cameras count.
  EXPECT_GT(result.camera_inliers[0], 70);
  EXPECT_GT(result.camera_inliers[1], 70);
  EXPECT_EQ(result.stats.inliers, result.camera_inliers[0] + result.camera_inliers[1]);
  ASSERT_EQ(result.inlier_masks.size(), 2u);
  EXPECT_EQ(result.inlier_masks[1].size(), 120u);
}

TEST(RigPnpTest, ACamerasBestIsNotRefinedAgainWhereARefinedPoseExplainsItsPoints) {
  // Both cameras see the truth: the first camera's refined best explains the second's points
  // as well as the second's own best does, so one refinement serves both.
  Rng rng(24);
  const RigPnpResult agreeing = SolveExpectingTheTruth(FrontBackObservations(120, 100, 0.3, rng));
  EXPECT_EQ(agreeing.stats.local_refinements, 1);
  // The front camera's points fit a pose 5 degrees off, which the back camera's contradict: the
  // front's refined best explains none of the back camera's points, so the back camera's best
  // is refined too. The front's 150 points outnumber the back's 100, so the front's pose wins.
  RigObservations contradicting;
  contradicting.cam_from_ref = FrontBackCamFromRef();
  const Rigid3d off(
      Eigen::Quaterniond(Eigen::AngleAxisd(5 * M_PI / 180, Eigen::Vector3d::UnitY())) *
          kTruth.rotation,
      kTruth.translation);
  contradicting.per_camera = {
      MakeObservations(off, 150, 0.5, 0.0, false, rng),
      MakeObservations(contradicting.cam_from_ref[1] * kTruth, 100, 0.5, 0.0, false, rng)};
  PnpRansacOptions options;
  options.refine.focal_px = kFocal;
  const RigPnpResult result = SolveRigPnpRansac(contradicting, options);
  ASSERT_TRUE(result.success);
  EXPECT_EQ(result.stats.local_refinements, 2);
  EXPECT_TRUE(ApproxEqual(result.ref_from_world, off, 0.01, 0.3));
}

TEST(RigPnpTest, ACoveredReferenceCameraLeavesThePoseToTheOther) {
  Rng rng(22);
  // The reference camera's pose, though it saw nothing.
  const RigPnpResult result = SolveExpectingTheTruth(FrontBackObservations(0, 150, 0.2, rng));
  ASSERT_EQ(result.camera_inliers.size(), 2u);
  EXPECT_EQ(result.camera_inliers[0], 0);
}

TEST(RigPnpTest, TwoViewsTightenThePoseOverOne) {
  Rng rng(23);
  const RigObservations both = FrontBackObservations(100, 100, 0.0, rng);
  RigObservations front_only = both;
  front_only.per_camera[1].clear();
  PoseRefineOptions options;
  options.focal_px = kFocal;
  Eigen::Matrix<double, 6, 6> both_covariance, front_covariance, mono_covariance;
  const Rigid3d refined = RefineRigPose(PerturbedStart(), both, options, nullptr, &both_covariance);
  EXPECT_TRUE(ApproxEqual(refined, kTruth, 0.01, 0.1));
  RefineRigPose(PerturbedStart(), front_only, options, nullptr, &front_covariance);
  // One camera at the identity is plain refinement.
  const Rigid3d mono =
      RefinePose(PerturbedStart(), both.per_camera[0], options, nullptr, &mono_covariance);
  EXPECT_TRUE(ApproxEqual(mono, RefineRigPose(PerturbedStart(), front_only, options), 1e-9, 1e-7));
  EXPECT_TRUE(front_covariance.isApprox(mono_covariance, 1e-6));
  // Opposite views pin the rotation and the position down: variances shrink by more than the
  // doubled count alone would give (half).
  EXPECT_LT(both_covariance.diagonal().head<3>().sum(),
            0.5 * front_covariance.diagonal().head<3>().sum());
  EXPECT_LT(both_covariance.diagonal().tail<3>().sum(),
            0.6 * front_covariance.diagonal().tail<3>().sum());
}

}  // namespace
}  // namespace visloc
