#include "core/camera/camera.h"

#include <gtest/gtest.h>

#include <cmath>

#include <Eigen/LU>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>

#include "core/util/check.h"

namespace visloc {
namespace {

// A strongly distorted wide-angle lens, like EuRoC's MT9M034 (k1 = -0.28).
Camera DistortedCamera() {
  return Camera(752, 480, 458.654, 457.296, 367.215, 248.375,
                       {-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05});
}

// A fisheye like TUM-VI's (equidistant, 190 deg nominal), here 170 deg across the diagonal.
Camera FisheyeCamera() {
  return Camera(512, 512, 190.98, 190.97, 254.93, 256.90,
                Lens::Equidistant(0.0034823, 0.0007150, -0.0020532, 0.0002029));
}

TEST(CameraTest, FovCameraHasExpectedFocalLength) {
  const Camera camera = Camera::FromHorizontalFov(320, 240, 90.0);
  EXPECT_NEAR(camera.fx(), 160.0, 1e-9);
  EXPECT_NEAR(camera.cx(), 159.5, 1e-12);
  // The image's left and right borders are at +-45 degrees.
  Eigen::Vector2d pixel;
  ASSERT_TRUE(camera.Project(Eigen::Vector3d(1.0, 0.0, 1.0), &pixel));
  EXPECT_NEAR(pixel.x(), 319.5, 1e-9);
}

TEST(CameraTest, ProjectUnprojectRoundTrip) {
  for (const Camera& camera : {Camera::FromHorizontalFov(640, 480, 90.0), DistortedCamera(),
                               FisheyeCamera(), Camera::FisheyeFromDiagonalFov(320, 240, 170)}) {
    for (double u = 0; u < camera.width(); u += 37.3) {
      for (double v = 0; v < camera.height(); v += 29.1) {
        const Eigen::Vector2d pixel(u, v);
        const Eigen::Vector3d ray = camera.Unproject(pixel);
        if (!ray.allFinite()) continue;  // A fisheye corner beyond 90 degrees.
        const Eigen::Vector3d point = 2.7 * ray;
        Eigen::Vector2d reprojected;
        ASSERT_TRUE(camera.Project(point, &reprojected));
        EXPECT_LT((reprojected - pixel).norm(), 1e-6) << "at " << pixel.transpose();
      }
    }
  }
}

// A query's keypoints are unprojected in batches (eight lanes for a radial-tangential lens):
// every ray and scale must be Unproject's and PixelScale's, bit for bit, including the lanes that
// converge in fewer iterations than their neighbours and the remainder after the last eight.
TEST(CameraTest, UnprojectManyEqualsUnprojectBitForBit) {
  for (const Camera& camera : {DistortedCamera(), Camera::FromHorizontalFov(640, 480, 90.0),
                               FisheyeCamera(), Camera::FisheyeFromDiagonalFov(320, 240, 170)}) {
    std::vector<Eigen::Vector2f> pixels;
    for (float u = -3.25f; u < camera.width() + 3; u += 13.7f) {
      for (float v = -2.5f; v < camera.height() + 2; v += 17.3f) pixels.emplace_back(u, v);
    }
    pixels.emplace_back(camera.cx(), camera.cy());  // Converges at once, beside slower lanes.
    ASSERT_NE(pixels.size() % 8, 0u);
    std::vector<Eigen::Vector2d> normalized;
    std::vector<double> scales;
    camera.UnprojectMany(pixels, &normalized, &scales);
    ASSERT_EQ(normalized.size(), pixels.size());
    ASSERT_EQ(scales.size(), pixels.size());
    int finite = 0;
    for (size_t i = 0; i < pixels.size(); ++i) {
      const Eigen::Vector3d ray = camera.Unproject(pixels[i].cast<double>());
      if (!ray.allFinite()) {
        EXPECT_FALSE(normalized[i].allFinite()) << pixels[i].transpose();
        continue;
      }
      ++finite;
      EXPECT_EQ(normalized[i].x(), ray.x()) << pixels[i].transpose();
      EXPECT_EQ(normalized[i].y(), ray.y()) << pixels[i].transpose();
      EXPECT_EQ(scales[i], camera.PixelScale(ray.head<2>())) << pixels[i].transpose();
    }
    EXPECT_GT(finite, 300);
  }
}

TEST(CameraTest, DistortionRoundTripWithinHundredthOfPixel) {
  const Camera camera = DistortedCamera();
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

TEST(CameraTest, PointsBehindTheCameraDoNotProject) {
  Eigen::Vector2d pixel(-1, -1);
  EXPECT_FALSE(DistortedCamera().Project(Eigen::Vector3d(0, 0, -1), &pixel));
  EXPECT_EQ(pixel, Eigen::Vector2d(-1, -1));
}

TEST(CameraTest, RejectsInvalidIntrinsics) {
  EXPECT_THROW(Camera(0, 240, 100, 100, 0, 0), CheckError);
  EXPECT_THROW(Camera(320, 240, -100, 100, 0, 0), CheckError);
}

TEST(CameraTest, ScaledCameraProjectsToScaledPixels) {
  const Camera camera = DistortedCamera();
  const Camera half = camera.Scaled(0.5);
  const Eigen::Vector3d point(0.3, -0.2, 2.0);
  Eigen::Vector2d full_px, half_px;
  ASSERT_TRUE(camera.Project(point, &full_px));
  ASSERT_TRUE(half.Project(point, &half_px));
  EXPECT_LT(((full_px.array() + 0.5) * 0.5 - 0.5 - half_px.array()).matrix().norm(), 1e-9);
}

TEST(CameraTest, EquidistantProjectsAsOpenCvFisheye) {
  const Camera camera = FisheyeCamera();
  std::vector<cv::Point3d> points;
  for (double a = -1.4; a <= 1.4; a += 0.2) {  // Up to 80 deg off axis.
    for (double b = -1.4; b <= 1.4; b += 0.35) {
      points.emplace_back(std::sin(a) * std::cos(b), std::sin(b), std::cos(a) * std::cos(b));
    }
  }
  cv::Mat k, d;
  cv::eigen2cv(camera.K(), k);
  const auto& c = camera.lens().coefficients;
  d = (cv::Mat_<double>(1, 4) << c[0], c[1], c[2], c[3]);
  std::vector<cv::Point2d> expected;
  cv::fisheye::projectPoints(points, expected, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), k, d);
  for (size_t i = 0; i < points.size(); ++i) {
    Eigen::Vector2d pixel;
    if (!camera.Project(Eigen::Vector3d(points[i].x, points[i].y, points[i].z), &pixel)) continue;
    EXPECT_NEAR(pixel.x(), expected[i].x, 1e-6);
    EXPECT_NEAR(pixel.y(), expected[i].y, 1e-6);
  }
}

TEST(CameraTest, FisheyeSeesNearly90DegreesOffAxisAndNothingBeyond) {
  const Camera camera = Camera::FisheyeFromDiagonalFov(320, 240, 170.0);
  // The image corner is 85 deg off axis.
  const Eigen::Vector3d corner = camera.Unproject(Eigen::Vector2d(-0.5, -0.5));
  ASSERT_TRUE(corner.allFinite());
  EXPECT_NEAR(std::atan(corner.head<2>().norm()) * 180 / M_PI, 85.0, 0.2);
  // Beyond the rim of a wider lens mapping: no ray with z = 1.
  const Camera narrow_f(320, 240, 60, 60, 159.5, 119.5, Lens::Equidistant(0, 0, 0, 0));
  EXPECT_FALSE(narrow_f.Unproject(Eigen::Vector2d(-0.5, -0.5)).allFinite());
}

TEST(CameraTest, PixelScaleIsTheLocalMagnification) {
  // A perfect pinhole: 1 everywhere. An equidistant fisheye: 1 at the centre, falling off with
  // the angle (at 60 deg, radial d(f theta)/d(tan theta) = cos^2 = 0.25 and tangential
  // theta / tan(theta) = 0.605: sqrt of their product 0.389).
  EXPECT_EQ(Camera::FromHorizontalFov(320, 240, 90).PixelScale({0.7, -0.3}), 1.0);
  const Camera fisheye = Camera::FisheyeFromDiagonalFov(320, 240, 170.0);
  EXPECT_NEAR(fisheye.PixelScale({0.0, 0.0}), 1.0, 1e-9);
  const double r = std::tan(M_PI / 3);
  EXPECT_NEAR(fisheye.PixelScale({r, 0.0}), std::sqrt(0.25 * (M_PI / 3) / r), 1e-6);
  // Numerically: pixels around a point, per unit of normalized coordinates.
  const Eigen::Vector2d n(0.9, 1.3), h(1e-6, 0), v(0, 1e-6);
  Eigen::Vector2d p0, px, py;
  fisheye.Project(Eigen::Vector3d(n.x(), n.y(), 1), &p0);
  fisheye.Project(Eigen::Vector3d(n.x() + h.x(), n.y(), 1), &px);
  fisheye.Project(Eigen::Vector3d(n.x(), n.y() + v.y(), 1), &py);
  Eigen::Matrix2d j;
  j.col(0) = (px - p0) / 1e-6;
  j.col(1) = (py - p0) / 1e-6;
  EXPECT_NEAR(fisheye.PixelScale(n), std::sqrt(std::abs(j.determinant())) / fisheye.fx(), 1e-5);
}

TEST(CameraTest, LensModelNamesRoundTrip) {
  for (LensModel model : {LensModel::kRadialTangential, LensModel::kEquidistant}) {
    EXPECT_EQ(ParseLensModel(LensModelName(model)), model);
  }
  EXPECT_EQ(ParseLensModel("radtan"), LensModel::kRadialTangential);
  EXPECT_THROW(ParseLensModel("kb8"), InputError);
  EXPECT_TRUE(Lens().IsIdeal());
  EXPECT_FALSE(Lens::Equidistant(0, 0, 0, 0).IsIdeal());
}

}  // namespace
}  // namespace visloc
