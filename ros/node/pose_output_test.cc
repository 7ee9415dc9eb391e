#include "ros/node/pose_output.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

namespace visloc::ros_node {
namespace {

v1::LocalizeResponse Answer(v1::Status status, bool has_pose) {
  v1::LocalizeResponse r;
  r.set_status(status);
  r.set_has_pose(has_pose);
  return r;
}

TEST(PoseOutputTest, PublishesOnlyPosesItCanStandBehind) {
  EXPECT_TRUE(IsPublishable(Answer(v1::STATUS_TRACKING, true)));
  EXPECT_TRUE(IsPublishable(Answer(v1::STATUS_RELOCALIZED, true)));
  EXPECT_TRUE(IsPublishable(Answer(v1::STATUS_LIMITED, true)));
  EXPECT_FALSE(IsPublishable(Answer(v1::STATUS_LOST, true)));  // Never a stale pose.
  EXPECT_FALSE(IsPublishable(Answer(v1::STATUS_TRACKING, false)));
  EXPECT_FALSE(IsPublishable(Answer(v1::STATUS_INITIALIZING, true)));
  EXPECT_FALSE(IsPublishable(Answer(v1::STATUS_ERROR, false)));
  EXPECT_FALSE(IsPublishable(Answer(v1::STATUS_SKIPPED, false)));
}

TEST(PoseOutputTest, CovarianceIsRotatedIntoTheMapFrame) {
  // A camera looking along the map's x axis (its z axis): depth uncertainty (camera z) becomes
  // map x uncertainty.
  const Eigen::Matrix3d map_from_cam_r =
      (Eigen::Matrix3d() << 0, 0, 1, -1, 0, 0, 0, -1, 0).finished();
  const Rigid3d map_from_cam(map_from_cam_r, Eigen::Vector3d(1, 2, 3));
  std::vector<double> cov(36, 0.0);
  cov[0] = 1e-4;              // camera x
  cov[2 * 6 + 2] = 9e-4;      // camera z (depth)
  cov[3 * 6 + 3] = 1e-6;      // rotation about camera x
  const auto map_cov = CovarianceInMapFrame(map_from_cam, cov);
  EXPECT_NEAR(map_cov[0], 9e-4, 1e-15);           // map x: the camera's depth
  EXPECT_NEAR(map_cov[1 * 6 + 1], 1e-4, 1e-15);   // map y: the camera's x
  EXPECT_NEAR(map_cov[4 * 6 + 4], 1e-6, 1e-15);   // rotation about map y
  EXPECT_EQ(CovarianceInMapFrame(map_from_cam, {})[0], 0.0);
}

TEST(PoseOutputTest, MapFromOdomClosesTheChain) {
  const Rigid3d map_from_cam(Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY())),
                             Eigen::Vector3d(1, 0, 2));
  const Rigid3d odom_from_cam(Eigen::Quaterniond(Eigen::AngleAxisd(-0.2, Eigen::Vector3d::UnitY())),
                              Eigen::Vector3d(0.5, 0.1, 0));
  const Rigid3d map_from_odom = MapFromOdom(map_from_cam, odom_from_cam);
  EXPECT_TRUE(ApproxEqual(map_from_odom * odom_from_cam, map_from_cam, 1e-12, 1e-12));
}

TEST(PoseOutputTest, OdometryBufferInterpolatesAndDoesNotInvent) {
  OdometryBuffer buffer;
  buffer.Add(1'000'000'000, Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0, 0)));
  buffer.Add(1'100'000'000, Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(1, 0, 0)));
  EXPECT_NEAR(buffer.At(1'050'000'000)->translation.x(), 0.5, 1e-9);
  constexpr int64_t kHoldNs = 100'000'000;  // Held 100 ms past the newest sample, when asked.
  EXPECT_NEAR(buffer.At(1'150'000'000, kHoldNs)->translation.x(), 1.0, 1e-9);  // 50 ms old.
  EXPECT_FALSE(buffer.At(1'500'000'000, kHoldNs).has_value());  // 400 ms past: unknown.
  EXPECT_FALSE(buffer.At(1'150'000'000).has_value());           // By default, never held.
  EXPECT_FALSE(buffer.At(900'000'000).has_value());                   // Before the first.
}

}  // namespace
}  // namespace visloc::ros_node

namespace visloc::ros_node {
namespace {

// REP 105's map is z up: the site pose when the server gives one and the node asks for it, the
// map frame's otherwise (a map that records no up, an older server, ~site_frame false).
TEST(PoseOutputTest, ThePublishedPoseIsTheSiteFramesWhenTheServerGivesIt) {
  v1::LocalizeResponse answer;
  proto::ToProto(Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(1, 2, 3)),
                 answer.mutable_map_from_cam());
  bool in_site = true;
  EXPECT_TRUE(PublishedPose(answer, true, &in_site).translation.isApprox(Eigen::Vector3d(1, 2, 3)));
  EXPECT_FALSE(in_site);
  proto::ToProto(Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(3, -1, -2)),
                 answer.mutable_site_from_cam());
  answer.set_site_frame("level");
  EXPECT_TRUE(
      PublishedPose(answer, true, &in_site).translation.isApprox(Eigen::Vector3d(3, -1, -2)));
  EXPECT_TRUE(in_site);
  EXPECT_TRUE(
      PublishedPose(answer, false, &in_site).translation.isApprox(Eigen::Vector3d(1, 2, 3)));
  EXPECT_FALSE(in_site);
}

}  // namespace
}  // namespace visloc::ros_node
