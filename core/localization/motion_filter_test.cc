#include "core/localization/motion_filter.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include "core/util/check.h"

namespace visloc {
namespace {

Rigid3d SomePose() {
  return Rigid3d(RotationFromRollPitchYaw(0.1, -0.2, 0.7), Eigen::Vector3d(0.5, -1.0, 2.0));
}

TEST(MotionFilterTest, ExpAndLogAreInverse) {
  Vector6d tangent;
  tangent << 0.1, -0.2, 0.3, 0.05, -0.02, 0.4;
  EXPECT_TRUE(LogSe3(ExpSe3(tangent)).isApprox(tangent, 1e-12));
  EXPECT_TRUE(ApproxEqual(ExpSe3(LogSe3(SomePose())), SomePose(), 1e-12, 1e-9));
}

TEST(MotionFilterTest, AdjointMovesAPerturbationAcrossATransform) {
  // T Exp(e) = Exp(Ad(T) e) T to first order, so for a small e the two agree closely.
  Vector6d e;
  e << 1e-4, -2e-4, 3e-4, 2e-4, 1e-4, -3e-4;
  const Rigid3d t = SomePose();
  const Rigid3d left = ExpSe3(Adjoint(t) * e) * t;
  const Rigid3d right = t * ExpSe3(e);
  EXPECT_LT((left.translation - right.translation).norm(), 1e-7);
  EXPECT_LT(RotationAngleDeg(left.rotation.inverse() * right.rotation), 1e-5);
}

TEST(MotionFilterTest, PredictionComposesMotionAndGrowsUncertainty) {
  MotionFilter filter;
  filter.Reset(SomePose(), Matrix6d::Identity() * 1e-6);
  const Rigid3d step(RotationFromRollPitchYaw(0, 0.05, 0), Eigen::Vector3d(0, 0, 0.1));
  filter.Predict(step, Matrix6d::Identity() * 1e-4);
  EXPECT_TRUE(ApproxEqual(filter.map_from_cam(), SomePose() * step, 1e-12, 1e-9));
  EXPECT_NEAR(filter.PositionSigmaM(), std::sqrt(1e-4 + 1e-6), 2e-4);
}

TEST(MotionFilterTest, PoseUpdateWeighsPriorAndMeasurementByTheirCovariances) {
  MotionFilter filter;
  filter.Reset(Rigid3d::Identity(), Matrix6d::Identity() * 0.01);
  const Rigid3d measured(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.2, 0, 0));
  // Equal covariances: the estimate moves half way and the variance halves.
  const double d2 = filter.UpdatePose(measured, Matrix6d::Identity() * 0.01);
  EXPECT_NEAR(filter.map_from_cam().translation.x(), 0.1, 1e-9);
  EXPECT_NEAR(filter.covariance()(0, 0), 0.005, 1e-9);
  EXPECT_NEAR(d2, 0.2 * 0.2 / 0.02, 1e-9);
  // The distance alone, the state untouched: the next update's own.
  const Rigid3d before = filter.map_from_cam();
  const double next = filter.InnovationDistanceSq(measured, Matrix6d::Identity() * 1e-8);
  EXPECT_TRUE(ApproxEqual(filter.map_from_cam(), before, 0, 0));
  // A far more precise measurement wins.
  EXPECT_DOUBLE_EQ(filter.UpdatePose(measured, Matrix6d::Identity() * 1e-8), next);
  EXPECT_NEAR(filter.map_from_cam().translation.x(), 0.2, 1e-5);
}

TEST(MotionFilterTest, HeightUpdateMovesOnlyAlongTheNormal) {
  MotionFilter filter;
  const Rigid3d start(RotationFromRollPitchYaw(0.3, 0.2, 0.1), Eigen::Vector3d(1.0, 2.0, 0.3));
  filter.Reset(start, Matrix6d::Identity() * 0.04);
  filter.UpdateHeight(Eigen::Vector3d::UnitZ(), 0.0, 0.0, 1e-4);
  EXPECT_NEAR(filter.map_from_cam().translation.z(), 0.0, 1e-3);
  EXPECT_NEAR(filter.map_from_cam().translation.x(), 1.0, 1e-9);
  EXPECT_NEAR(filter.map_from_cam().translation.y(), 2.0, 1e-9);
  EXPECT_THROW(filter.UpdateHeight(Eigen::Vector3d::UnitZ(), 0, 0, 0.0), CheckError);
}

TEST(MotionFilterTest, UseBeforeResetIsAnError) {
  MotionFilter filter;
  EXPECT_FALSE(filter.initialized());
  EXPECT_THROW(filter.Predict(Rigid3d::Identity(), Matrix6d::Zero()), CheckError);
}

}  // namespace
}  // namespace visloc
