#include "client/lib/pose_math.h"

#include <gtest/gtest.h>

#include <cmath>

namespace visloc::client {
namespace {

v1::Pose MakePose(double yaw_rad, double tx, double ty, double tz) {
  v1::Pose p;
  p.set_qw(std::cos(yaw_rad / 2));
  p.set_qz(std::sin(yaw_rad / 2));
  p.set_tx(tx);
  p.set_ty(ty);
  p.set_tz(tz);
  return p;
}

void ExpectNear(const v1::Pose& a, const v1::Pose& b) {
  EXPECT_NEAR(a.tx(), b.tx(), 1e-12);
  EXPECT_NEAR(a.ty(), b.ty(), 1e-12);
  EXPECT_NEAR(a.tz(), b.tz(), 1e-12);
  // q and -q are the same rotation.
  const double dot = a.qw() * b.qw() + a.qx() * b.qx() + a.qy() * b.qy() + a.qz() * b.qz();
  EXPECT_NEAR(std::abs(dot), 1.0, 1e-12);
}

TEST(PoseMathTest, ComposeAndInvertAreRigidTransforms) {
  const v1::Pose a = MakePose(M_PI / 2, 1, 0, 0);
  const v1::Pose b = MakePose(0, 1, 0, 0);
  // A quarter turn about z then a metre along the rotated x: (1, 1, 0).
  ExpectNear(Compose(a, b), MakePose(M_PI / 2, 1, 1, 0));
  ExpectNear(Compose(a, Invert(a)), MakePose(0, 0, 0, 0));
  ExpectNear(Invert(Invert(a)), a);
}

// The robot moved 2 m forward (its x) and turned 90 degrees by its odometry, whose origin is
// anywhere: the map pose moves by the same motion.
TEST(PoseMathTest, OdometryMovesTheLastPoseByItsMotionOnly) {
  const v1::Pose map_then = MakePose(M_PI / 2, 5, 5, 0);
  const v1::Pose odom_then = MakePose(-0.3, 100, -40, 1);
  const v1::Pose motion = MakePose(M_PI / 2, 2, 0, 0);
  const v1::Pose odom_now = Compose(odom_then, motion);
  ExpectNear(PropagateByOdometry(map_then, odom_then, odom_now), Compose(map_then, motion));
  ExpectNear(PropagateByOdometry(map_then, odom_then, odom_now), MakePose(M_PI, 5, 7, 0));
}

}  // namespace
}  // namespace visloc::client
