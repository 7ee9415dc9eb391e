#include "core/geometry/rigid3.h"

#include <gtest/gtest.h>

namespace visloc {
namespace {

Rigid3d SomePose() {
  return Rigid3d(RotationFromRollPitchYaw(0.1, -0.2, 0.7), Eigen::Vector3d(1.0, -2.0, 0.5));
}

TEST(Rigid3dTest, InverseComposesToIdentity) {
  const Rigid3d a_from_b = SomePose();
  EXPECT_TRUE(ApproxEqual(a_from_b * a_from_b.Inverse(), Rigid3d::Identity(), 1e-12, 1e-9));
  const Eigen::Vector3d point_in_b(0.3, 0.4, 5.0);
  const Eigen::Vector3d point_in_a = a_from_b * point_in_b;
  EXPECT_TRUE((a_from_b.Inverse() * point_in_a).isApprox(point_in_b, 1e-12));
}

TEST(Rigid3dTest, CompositionMatchesMatrices) {
  const Rigid3d a_from_b = SomePose();
  const Rigid3d b_from_c(RotationFromRollPitchYaw(-0.3, 0.05, 2.0), Eigen::Vector3d(0, 1, 2));
  const Eigen::Matrix4d expected = a_from_b.ToMatrix4() * b_from_c.ToMatrix4();
  EXPECT_TRUE((a_from_b * b_from_c).ToMatrix4().isApprox(expected, 1e-12));
  EXPECT_TRUE(
      ApproxEqual(Rigid3d::FromMatrix(expected.topRows<3>()), a_from_b * b_from_c, 1e-12, 1e-9));
}

TEST(Rigid3dTest, RollPitchYawConvention) {
  // Yaw of 90 degrees turns the x axis onto the y axis (z up).
  const Eigen::Vector3d x_rotated =
      RotationFromRollPitchYaw(0, 0, M_PI / 2) * Eigen::Vector3d::UnitX();
  EXPECT_TRUE(x_rotated.isApprox(Eigen::Vector3d::UnitY(), 1e-12));
  EXPECT_NEAR(RotationAngleDeg(RotationFromRollPitchYaw(0, 0, 0.5)), 0.5 * 180 / M_PI, 1e-9);
}

TEST(Rigid3dTest, InterpolateHalfway) {
  const Rigid3d start = Rigid3d::Identity();
  const Rigid3d end(RotationFromRollPitchYaw(0, 0, 1.0), Eigen::Vector3d(2, 0, 0));
  const Rigid3d mid = Interpolate(start, end, 0.5);
  EXPECT_TRUE(mid.translation.isApprox(Eigen::Vector3d(1, 0, 0)));
  EXPECT_NEAR(RotationAngleDeg(mid.rotation), 0.5 * 180 / M_PI, 1e-9);
}

}  // namespace
}  // namespace visloc
