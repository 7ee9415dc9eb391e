#include "sim/walking_path.h"

#include <gtest/gtest.h>

#include "core/util/check.h"
#include "sim/sequences.h"

namespace visloc::sim {
namespace {

TEST(WalkingPathTest, SquareLoopReturnsToItsStart) {
  const SequenceSpec spec = MakeSequenceSpec("map_square", 1);
  const WalkingPath& path = spec.path;
  EXPECT_NEAR(path.length_m(), 8.0, 1e-12);
  const PlanarPose start = path.PlannedAt(0), end = path.PlannedAt(path.duration_s());
  EXPECT_NEAR(start.x, end.x, 1e-9);
  EXPECT_NEAR(start.y, end.y, 1e-9);
  EXPECT_NEAR(std::remainder(end.yaw - start.yaw, 2 * M_PI), 0.0, 1e-9);
  // Corners of the square.
  const PlanarPose corner = path.PlannedAt(path.duration_s() / 4 - 1e-9);
  EXPECT_NEAR(corner.x, 1.0, 1e-6);
  EXPECT_NEAR(corner.y, -1.0, 1e-6);
}

TEST(WalkingPathTest, HumanoidSpeedHeightAndHeadBob) {
  const GaitOptions gait;
  WalkingPath path({0, 0, 0}, gait);
  path.Walk(3.0);
  double min_z = 1e9, max_z = -1e9, max_speed = 0;
  for (double t = 1.0; t < path.duration_s() - 1.0; t += 0.01) {
    const Rigid3d pose = path.WorldFromBody(t);
    min_z = std::min(min_z, pose.translation.z());
    max_z = std::max(max_z, pose.translation.z());
    const PlanarPose a = path.PlannedAt(t), b = path.PlannedAt(t + 0.01);
    max_speed = std::max(max_speed, std::hypot(b.x - a.x, b.y - a.y) / 0.01);
  }
  EXPECT_NEAR(0.5 * (min_z + max_z), 1.45, 0.002);
  EXPECT_GE(max_z - min_z, 0.01);  // head bob of 1-2 cm peak to peak
  EXPECT_LE(max_z - min_z, 0.02);
  EXPECT_GE(max_speed, 0.2);
  EXPECT_LE(max_speed, 0.25);
}

// The body's forward axis (x) on the floor, as a heading.
double HeadingOf(const Rigid3d& world_from_body) {
  const Eigen::Vector3d forward = world_from_body.rotation * Eigen::Vector3d::UnitX();
  return std::atan2(forward.y(), forward.x());
}

TEST(WalkingPathTest, OutwardCircleLooksAwayFromItsCentreAllRoundTheCircle) {
  const SequenceSpec spec = MakeSequenceSpec("outward", 1);
  const WalkingPath& path = spec.path;
  for (double t = 0.5; t < path.duration_s(); t += 0.5) {
    const Rigid3d body = path.WorldFromBody(t);
    const Eigen::Vector2d from_centre = body.translation.head<2>();
    EXPECT_NEAR(from_centre.norm(), 0.8, 0.02) << t;
    // Facing out, within the gait's sway and roll.
    EXPECT_NEAR(std::remainder(HeadingOf(body) - std::atan2(from_centre.y(), from_centre.x()),
                               2 * M_PI),
                0.0, 0.03)
        << t;
    // The plan (and so the odometry) turns the same way.
    EXPECT_NEAR(std::remainder(path.PlannedAt(t).yaw - HeadingOf(body), 2 * M_PI), 0.0, 0.03);
  }
}

TEST(WalkingPathTest, GlancesTurnTheHeadOverTheShoulderAndBack) {
  GaitOptions gait;
  gait.glance_yaw_rad = 2.0;
  gait.glance_period_s = 6.0;
  gait.glance_s = 2.0;
  WalkingPath path({0, 0, 0}, gait);
  path.Walk(3.0);
  EXPECT_DOUBLE_EQ(path.HeadYawAt(1.0), 0.0);  // Walking ahead...
  EXPECT_NEAR(path.HeadYawAt(5.0), 2.0, 1e-12);  // ...the glance's peak, mid-glance...
  EXPECT_NEAR(path.HeadYawAt(6.0 - 1e-9), 0.0, 1e-6);  // ...and ahead again.
  EXPECT_NEAR(path.HeadYawAt(11.0), 2.0, 1e-12);  // Every period.
  EXPECT_NEAR(std::remainder(HeadingOf(path.WorldFromBody(5.0)) - 2.0, 2 * M_PI), 0.0, 0.03);
  // The feet walk on along x: the head turns, the path does not.
  EXPECT_NEAR(path.WorldFromBody(5.0).translation.y(), 0.0, 0.01);
  gait.glance_s = 7.0;
  EXPECT_THROW(WalkingPath({0, 0, 0}, gait), visloc::CheckError);
}

TEST(WalkingPathTest, KidnapCarriesTheRobotWithoutStepping) {
  const SequenceSpec spec = MakeSequenceSpec("kidnap", 1);
  const auto carried = spec.path.CarriedIntervals();
  ASSERT_EQ(carried.size(), 1u);
  const auto [start, end] = carried.front();
  const PlanarPose before = spec.path.PlannedAt(start), after = spec.path.PlannedAt(end);
  EXPECT_NEAR(std::hypot(after.x - before.x, after.y - before.y), 1.4, 1e-9);
  EXPECT_FALSE(spec.path.SteppingAt(0.5 * (start + end)));
  ASSERT_EQ(spec.covered_s.size(), 1u);
  EXPECT_NEAR(spec.covered_s[0].second - spec.covered_s[0].first, 1.2, 1e-9);
}

}  // namespace
}  // namespace visloc::sim
