#include "core/eval/trajectory_eval.h"

#include <gtest/gtest.h>

namespace visloc {
namespace {

// A 10 s walk along a curve at 15 Hz with changing orientation.
Trajectory MakeGroundTruth() {
  Trajectory gt;
  for (int i = 0; i < 150; ++i) {
    const double t = i / 15.0;
    gt.push_back({SecondsToNs(100.0 + t),
                  Rigid3d(RotationFromRollPitchYaw(0.05 * std::sin(t), 0.02 * t, 0.3 * t),
                          Eigen::Vector3d(std::cos(0.3 * t), std::sin(0.3 * t), 0.01 * t))});
  }
  return gt;
}

TEST(TrajectoryEvalTest, GroundTruthAgainstItselfIsZero) {
  const Trajectory gt = MakeGroundTruth();
  EvalOptions options;
  options.align = true;
  const TrajectoryEvaluation eval = EvaluateTrajectory(gt, gt, options);
  EXPECT_EQ(eval.matched_poses, gt.size());
  EXPECT_DOUBLE_EQ(eval.coverage, 1.0);
  EXPECT_NEAR(eval.ate.translation_m.rmse, 0.0, 1e-12);
  EXPECT_NEAR(eval.ate.rotation_deg.max, 0.0, 1e-6);
  EXPECT_NEAR(eval.ate_aligned->translation_m.max, 0.0, 1e-9);
  EXPECT_NEAR(eval.rpe.translation_m.max, 0.0, 1e-12);
  EXPECT_GT(eval.rpe.translation_m.count, 100u);
}

TEST(TrajectoryEvalTest, KnownOffsetComesOutExactly) {
  const Trajectory gt = MakeGroundTruth();
  // The same trajectory seen from a frame shifted by 5 cm along x: map_from_est = offset.
  const Rigid3d offset(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.05, 0.0, 0.0));
  Trajectory est;
  for (const StampedPose& p : gt) est.push_back({p.timestamp_ns, offset * p.pose});
  EvalOptions options;
  options.align = true;
  const TrajectoryEvaluation eval = EvaluateTrajectory(gt, est, options);
  EXPECT_NEAR(eval.ate.translation_m.rmse, 0.05, 1e-12);
  EXPECT_NEAR(eval.ate.translation_m.median, 0.05, 1e-12);
  EXPECT_NEAR(eval.ate.translation_m.max, 0.05, 1e-12);
  EXPECT_NEAR(eval.ate.rotation_deg.max, 0.0, 1e-6);
  // Alignment removes a pure frame offset, and RPE never sees it.
  EXPECT_NEAR(eval.ate_aligned->translation_m.max, 0.0, 1e-9);
  EXPECT_TRUE(eval.gt_from_est.translation.isApprox(Eigen::Vector3d(-0.05, 0, 0), 1e-9));
  EXPECT_NEAR(eval.rpe.translation_m.max, 0.0, 1e-12);
}

TEST(TrajectoryEvalTest, KnownRotationComesOutExactly) {
  const Trajectory gt = MakeGroundTruth();
  // Each camera rotated by 2 degrees about its own optical axis: positions unchanged.
  const Rigid3d cam_twist(
      Eigen::Quaterniond(Eigen::AngleAxisd(2.0 * M_PI / 180, Eigen::Vector3d::UnitZ())),
      Eigen::Vector3d::Zero());
  Trajectory est;
  for (const StampedPose& p : gt) est.push_back({p.timestamp_ns, p.pose * cam_twist});
  const TrajectoryEvaluation eval = EvaluateTrajectory(gt, est, EvalOptions{});
  EXPECT_NEAR(eval.ate.translation_m.max, 0.0, 1e-12);
  EXPECT_NEAR(eval.ate.rotation_deg.median, 2.0, 1e-9);
  EXPECT_NEAR(eval.ate.rotation_deg.max, 2.0, 1e-9);
}

TEST(TrajectoryEvalTest, GroundTruthInItsOwnWorldFrameComparesFromItsFirstPose) {
  const Trajectory map_frame_gt = MakeGroundTruth();  // Starts at (1, 0, 0), turned.
  // The same motion as a recording's ground truth gives it: in a world frame of its own.
  const Rigid3d world_from_map(RotationFromRollPitchYaw(0.1, -0.2, 1.0),
                               Eigen::Vector3d(3.0, -4.0, 0.5));
  Trajectory world_gt;
  for (const StampedPose& p : map_frame_gt)
    world_gt.push_back({p.timestamp_ns, world_from_map * p.pose});
  // The estimate of a map built from the first frame: the first pose is the origin.
  const Rigid3d first_from_map = map_frame_gt.front().pose.Inverse();
  Trajectory est;
  for (const StampedPose& p : map_frame_gt)
    est.push_back({p.timestamp_ns, first_from_map * p.pose});
  EvalOptions options;
  EXPECT_GT(EvaluateTrajectory(world_gt, est, options).ate.translation_m.max, 1.0);
  options.gt_origin_first = true;
  const TrajectoryEvaluation eval = EvaluateTrajectory(world_gt, est, options);
  EXPECT_NEAR(eval.ate.translation_m.max, 0.0, 1e-9);
  EXPECT_NEAR(eval.ate.rotation_deg.max, 0.0, 1e-6);
}

TEST(TrajectoryEvalTest, ErrorPerDistanceTravelledIsADriftShare) {
  // A straight 10 m drive whose estimate is 1% too long: the error is 1% of the path throughout.
  Trajectory gt, est;
  for (int i = 0; i <= 10; ++i) {
    const int64_t t = SecondsToNs(i);
    gt.push_back({t, Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0, i))});
    est.push_back({t, Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0, 1.01 * i))});
  }
  const TrajectoryEvaluation eval = EvaluateTrajectory(gt, est, EvalOptions{});
  EXPECT_EQ(eval.ate_per_distance.count, 10u);  // The first pose has travelled nothing.
  // A still camera's wandering ground truth travels no distance to share an error over.
  Trajectory still;
  for (int i = 0; i < 50; ++i) {
    still.push_back({SecondsToNs(i), Rigid3d(Eigen::Quaterniond::Identity(),
                                             Eigen::Vector3d(0.001 * (i % 2), 0, 0))});
  }
  EXPECT_EQ(EvaluateTrajectory(still, still, EvalOptions{}).ate_per_distance.count, 0u);
  EXPECT_NEAR(eval.ate_per_distance.median, 0.01, 1e-12);
  EXPECT_NEAR(eval.ate_per_distance.max, 0.01, 1e-12);
}

TEST(TrajectoryEvalTest, ConsistencyCountsErrorsInSigmas) {
  const Trajectory gt = MakeGroundTruth();
  Trajectory est;
  std::vector<Eigen::Matrix3d> covariances;
  for (size_t i = 0; i < gt.size(); ++i) {
    // Every tenth estimate 7 sigma off, the others 1 sigma; one estimate reports no sigma.
    const double sigma = 0.01, off = (i % 10 == 0 ? 7.0 : 1.0) * sigma;
    est.push_back(
        {gt[i].timestamp_ns,
         Rigid3d(gt[i].pose.rotation, gt[i].pose.translation + Eigen::Vector3d(0, off, 0))});
    covariances.push_back(Eigen::Matrix3d::Identity() * (i == 5 ? 0.0 : sigma * sigma));
  }
  const ConsistencyEvaluation c = EvaluateConsistency(gt, est, covariances, EvalOptions{});
  EXPECT_EQ(c.compared, gt.size() - 1);
  EXPECT_NEAR(c.normalized_error.median, 1.0, 1e-9);
  EXPECT_NEAR(c.normalized_error.max, 7.0, 1e-9);
  EXPECT_NEAR(c.beyond_3_sigma, 15.0 / 149.0, 1e-12);
  EXPECT_NEAR(c.beyond_6_sigma, 15.0 / 149.0, 1e-12);
}

// An anisotropic covariance measures each error along its own axes: 1 cm along an axis of
// sigma 1 cm is 1 sigma; along an axis of sigma 1 mm it is 10, though the per-axis sigma
// sqrt(trace / 3) would call it 1.7.
TEST(TrajectoryEvalTest, ConsistencyIsTheMahalanobisDistanceInTheFullCovariance) {
  const Trajectory gt = MakeGroundTruth();
  Trajectory est;
  std::vector<Eigen::Matrix3d> covariances;
  const Eigen::Matrix3d covariance = Eigen::Vector3d(1e-4, 1e-6, 1e-4).asDiagonal();
  for (size_t i = 0; i < gt.size(); ++i) {
    const Eigen::Vector3d off = i % 2 == 0 ? Eigen::Vector3d(0.01, 0, 0) : Eigen::Vector3d(0, 0.01, 0);
    est.push_back({gt[i].timestamp_ns, Rigid3d(gt[i].pose.rotation, gt[i].pose.translation + off)});
    covariances.push_back(i == 3 ? Eigen::Matrix3d::Zero() : covariance);  // One reports none.
  }
  const ConsistencyEvaluation c = EvaluateConsistency(gt, est, covariances, EvalOptions{});
  EXPECT_EQ(c.compared, gt.size() - 1);
  EXPECT_NEAR(c.normalized_error.min, 1.0, 1e-9);
  EXPECT_NEAR(c.normalized_error.max, 10.0, 1e-9);
  EXPECT_NEAR(c.beyond_6_sigma, 74.0 / 149.0, 1e-12);
}

TEST(TrajectoryEvalTest, CoverageCountsOnlyAssociatedPoses) {
  const Trajectory gt = MakeGroundTruth();
  Trajectory est;
  for (size_t i = 0; i < gt.size(); i += 3) {
    // Estimates 5 ms late: within the 20 ms association tolerance.
    est.push_back({gt[i].timestamp_ns + 5'000'000, gt[i].pose});
  }
  est.push_back({gt.back().timestamp_ns + SecondsToNs(5.0), gt.back().pose});  // no partner
  const TrajectoryEvaluation eval = EvaluateTrajectory(gt, est, EvalOptions{});
  EXPECT_EQ(eval.matched_poses, 50u);
  EXPECT_NEAR(eval.coverage, 50.0 / 150.0, 1e-12);
}

TEST(TrajectoryEvalTest, ErrorStatsOfKnownList) {
  const ErrorStats stats = ComputeErrorStats({3.0, 4.0, 1.0, 2.0});
  EXPECT_EQ(stats.count, 4u);
  EXPECT_DOUBLE_EQ(stats.median, 2.5);
  EXPECT_DOUBLE_EQ(stats.mean, 2.5);
  EXPECT_DOUBLE_EQ(stats.max, 4.0);
  EXPECT_DOUBLE_EQ(stats.rmse, std::sqrt(30.0 / 4.0));
}

TEST(TrajectorySpreadTest, DeviationsFromTheMeanPoseOfAStillCamera) {
  // Four poses at the corners of a 2 mm square around (1, 2, 3), turned +-0.1 deg about z.
  Trajectory poses;
  const double d = 0.001, a = 0.1 * M_PI / 180.0;
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector3d offset(i % 2 ? d : -d, i / 2 ? d : -d, 0.0);
    const Eigen::Quaterniond q(Eigen::AngleAxisd(i % 2 ? a : -a, Eigen::Vector3d::UnitZ()));
    // The sign of a quaternion does not change its rotation.
    poses.push_back({i, Rigid3d(i == 3 ? Eigen::Quaterniond(-q.coeffs()) : q,
                                Eigen::Vector3d(1, 2, 3) + offset)});
  }
  const TrajectorySpread spread = ComputeSpread(poses);
  EXPECT_EQ(spread.poses, 4u);
  EXPECT_TRUE(spread.mean_position.isApprox(Eigen::Vector3d(1, 2, 3), 1e-12));
  EXPECT_NEAR(spread.position_m.max, std::sqrt(2.0) * d, 1e-12);
  EXPECT_NEAR(spread.rotation_deg.max, 0.1, 1e-9);
  EXPECT_NEAR(spread.rotation_deg.min, 0.1, 1e-9);
  EXPECT_EQ(ComputeSpread({}).poses, 0u);
}

}  // namespace
}  // namespace visloc
