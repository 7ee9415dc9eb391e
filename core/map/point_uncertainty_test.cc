// Point covariances against the closed forms of one and two stereo observations.

#include "core/map/point_uncertainty.h"

#include <gtest/gtest.h>

#include <cmath>

#include <Eigen/Eigenvalues>

namespace visloc {
namespace {

constexpr double kFocalPx = 160.0;

// A map of one point at `point_in_map`, seen by keyframes at `centres` looking down +z (rotated
// by `yaw_rad` about y each, so that each looks at the point from its own side).
Map OnePointMap(const Eigen::Vector3d& point_in_map,
                const std::vector<std::pair<Eigen::Vector3d, double>>& centres_and_yaws) {
  Map map;
  map.metadata.name = "one point";
  map.camera = Camera(320, 240, kFocalPx, kFocalPx, 159.5, 119.5);
  map.points.push_back({point_in_map, static_cast<uint32_t>(centres_and_yaws.size()), 0.3f});
  for (const auto& [centre, yaw_rad] : centres_and_yaws) {
    const Eigen::Quaterniond rotation(Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitY()));
    map.keyframes.push_back({0, Rigid3d(rotation, centre)});
    map.observations.push_back({static_cast<uint32_t>(map.keyframes.size() - 1), 0, {160, 120}});
  }
  return map;
}

TEST(PointUncertaintyTest, OneHeadOnStereoViewPinsThePointAcrossItsRayFarBetterThanAlongIt) {
  // 4 m straight ahead, 0.1 m baseline: across, 4 m * 0.5 px / 160 px = 12.5 mm; along, the
  // stereo depth's z^2 * 0.3 px / (f b) = 16 * 0.3 / 16 = 0.3 m.
  const Map map = OnePointMap({0, 0, 4}, {{Eigen::Vector3d::Zero(), 0.0}});
  const Eigen::Matrix3d covariance = Unpack(PointCovariances(map, 0.1)[0]);
  EXPECT_NEAR(std::sqrt(covariance(0, 0)), 0.0125, 1e-5);
  EXPECT_NEAR(std::sqrt(covariance(1, 1)), 0.0125, 1e-5);
  EXPECT_NEAR(std::sqrt(covariance(2, 2)), 0.3, 1e-3);
  EXPECT_NEAR(covariance(0, 2), 0.0, 1e-9);
}

TEST(PointUncertaintyTest, ASecondViewFromTheSidePinsTheDepthTheFirstLeftLoose) {
  // The second keyframe 4 m to the side, turned 90 degrees to face the point: its ray is the
  // first one's depth axis, which it pins to its own across-ray sigma.
  const Eigen::Vector3d point(0, 0, 4);
  const Map head_on = OnePointMap(point, {{Eigen::Vector3d::Zero(), 0.0}});
  const Map both = OnePointMap(point, {{Eigen::Vector3d::Zero(), 0.0},
                                       {Eigen::Vector3d(-4, 0, 4), M_PI / 2}});
  const double head_on_depth_m = std::sqrt(Unpack(PointCovariances(head_on, 0.1)[0])(2, 2));
  const Eigen::Matrix3d covariance = Unpack(PointCovariances(both, 0.1)[0]);
  EXPECT_GT(head_on_depth_m, 0.25);
  // 12.5 mm from the side view, and a little less with the first view's stereo along it.
  EXPECT_LT(std::sqrt(covariance(2, 2)), 0.0125);
  EXPECT_GT(std::sqrt(covariance(2, 2)), 0.012);
  // x is the second view's depth, pinned by the first view across its ray.
  EXPECT_LT(std::sqrt(covariance(0, 0)), 0.0125);
}

TEST(PointUncertaintyTest, WithoutABaselineOneViewLeavesTheDepthAtItsCap) {
  const Map map = OnePointMap({0, 0, 4}, {{Eigen::Vector3d::Zero(), 0.0}});
  PointUncertaintyOptions options;
  options.max_sigma_m = 5.0;
  const Eigen::Matrix3d covariance = Unpack(PointCovariances(map, 0.0, options)[0]);
  EXPECT_NEAR(std::sqrt(covariance(2, 2)), 5.0, 1e-6);
  EXPECT_NEAR(std::sqrt(covariance(0, 0)), 0.0125, 1e-5);
  // Packed and unpacked, a symmetric positive definite matrix.
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(covariance);
  EXPECT_GT(eigen.eigenvalues().minCoeff(), 0.0);
  EXPECT_TRUE(Unpack(Pack(covariance)).isApprox(covariance, 1e-6));
}

}  // namespace
}  // namespace visloc
