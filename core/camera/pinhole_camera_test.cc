#include "core/camera/pinhole_camera.h"

#include <gtest/gtest.h>

#include "core/util/check.h"

namespace visloc {
namespace {

// A strongly distorted wide-angle lens, like EuRoC's MT9M034 (k1 = -0.28).
PinholeCamera DistortedCamera() {
  return PinholeCamera(752, 480, 458.654, 457.296, 367.215, 248.375,
                       {-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05});
}

TEST(PinholeCameraTest, FovCameraHasExpectedFocalLength) {
  const PinholeCamera camera = PinholeCamera::FromHorizontalFov(320, 240, 90.0);
  EXPECT_NEAR(camera.fx(), 160.0, 1e-9);
  EXPECT_NEAR(camera.cx(), 159.5, 1e-12);
  // The image's left and right borders are at +-45 degrees.
  Eigen::Vector2d pixel;
  ASSERT_TRUE(camera.Project(Eigen::Vector3d(1.0, 0.0, 1.0), &pixel));
  EXPECT_NEAR(pixel.x(), 319.5, 1e-9);
}

TEST(PinholeCameraTest, ProjectUnprojectRoundTrip) {
  for (const PinholeCamera& camera :
       {PinholeCamera::FromHorizontalFov(640, 480, 90.0), DistortedCamera()}) {
    for (double u = 0; u < camera.width(); u += 37.3) {
      for (double v = 0; v < camera.height(); v += 29.1) {
        const Eigen::Vector2d pixel(u, v);
        const Eigen::Vector3d point = 2.7 * camera.Unproject(pixel);
        Eigen::Vector2d reprojected;
        ASSERT_TRUE(camera.Project(point, &reprojected));
        EXPECT_LT((reprojected - pixel).norm(), 1e-6) << "at " << pixel.transpose();
      }
    }
  }
}

TEST(PinholeCameraTest, DistortionRoundTripWithinHundredthOfPixel) {
  const PinholeCamera camera = DistortedCamera();
  double worst_px = 0.0;
  for (double u = 0; u < camera.width(); u += 11.0) {
    for (double v = 0; v < camera.height(); v += 11.0) {
      const Eigen::Vector2d distorted((u - camera.cx()) / camera.fx(),
                                      (v - camera.cy()) / camera.fy());
      const Eigen::Vector2d back = camera.Distort(camera.Undistort(distorted));
      worst_px = std::max(
          worst_px,
          ((back - distorted).array() * Eigen::Array2d(camera.fx(), camera.fy())).matrix().norm());
    }
  }
  EXPECT_LT(worst_px, 0.01);
}

TEST(PinholeCameraTest, PointsBehindTheCameraDoNotProject) {
  Eigen::Vector2d pixel(-1, -1);
  EXPECT_FALSE(DistortedCamera().Project(Eigen::Vector3d(0, 0, -1), &pixel));
  EXPECT_EQ(pixel, Eigen::Vector2d(-1, -1));
}

TEST(PinholeCameraTest, RejectsInvalidIntrinsics) {
  EXPECT_THROW(PinholeCamera(0, 240, 100, 100, 0, 0), CheckError);
  EXPECT_THROW(PinholeCamera(320, 240, -100, 100, 0, 0), CheckError);
}

TEST(PinholeCameraTest, ScaledCameraProjectsToScaledPixels) {
  const PinholeCamera camera = DistortedCamera();
  const PinholeCamera half = camera.Scaled(0.5);
  const Eigen::Vector3d point(0.3, -0.2, 2.0);
  Eigen::Vector2d full_px, half_px;
  ASSERT_TRUE(camera.Project(point, &full_px));
  ASSERT_TRUE(half.Project(point, &half_px));
  EXPECT_LT(((full_px.array() + 0.5) * 0.5 - 0.5 - half_px.array()).matrix().norm(), 1e-9);
}

}  // namespace
}  // namespace visloc
