#include "core/geometry/trajectory.h"

#include <gtest/gtest.h>

namespace visloc {
namespace {

TEST(TrajectoryTest, InterpolatesInsideAndRefusesOutsideOrAcrossGaps) {
  const Trajectory trajectory = {
      {1000, Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0, 0))},
      {2000, Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(1, 0, 0))},
      {9000, Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(2, 0, 0))},
  };
  EXPECT_NEAR(InterpolateAt(trajectory, 1250, 5000)->translation.x(), 0.25, 1e-12);
  EXPECT_NEAR(InterpolateAt(trajectory, 2000, 5000)->translation.x(), 1.0, 1e-12);
  EXPECT_FALSE(InterpolateAt(trajectory, 999, 5000));
  EXPECT_FALSE(InterpolateAt(trajectory, 9001, 5000));
  EXPECT_FALSE(InterpolateAt(trajectory, 5000, 5000));  // the 7000 ns gap is too long
}

TEST(TrajectoryTest, RelativeToFirstStartsAtIdentity) {
  const Rigid3d first(RotationFromRollPitchYaw(0.1, 0.2, 0.3), Eigen::Vector3d(1, 2, 3));
  const Rigid3d second = first * Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0, 1));
  const Trajectory relative = RelativeTo({{0, first}, {1, second}}, first);
  EXPECT_TRUE(ApproxEqual(relative[0].pose, Rigid3d::Identity(), 1e-12, 1e-9));
  EXPECT_TRUE(relative[1].pose.translation.isApprox(Eigen::Vector3d(0, 0, 1), 1e-12));
}

}  // namespace
}  // namespace visloc
