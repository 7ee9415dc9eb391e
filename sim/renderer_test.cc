#include "sim/renderer.h"

#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include "sim/sequences.h"

namespace visloc::sim {
namespace {

constexpr double kTexel = 0.002;

// A 4 m x 3 m wall at y = 2.5 m facing a camera at the origin, white with dark discs of 3 cm
// radius at known wall coordinates.
struct DiscWall {
  World world;
  std::vector<Eigen::Vector3d> disc_centers_world;

  DiscWall() {
    cv::Mat albedo(static_cast<int>(3.0 / kTexel), static_cast<int>(4.0 / kTexel), CV_8UC1,
                   cv::Scalar(230));
    Surface wall;
    wall.origin = Eigen::Vector3d(-2.0, 2.5, 1.5);
    wall.u_axis = Eigen::Vector3d::UnitX();
    wall.v_axis = -Eigen::Vector3d::UnitZ();
    wall.size_u_m = 4.0;
    wall.size_v_m = 3.0;
    for (double u : {0.7, 1.6, 2.05, 2.9, 3.5}) {
      for (double v : {0.6, 1.35, 2.2}) {
        // OpenCV draws with pixel centres at integer coordinates; Texture puts texel centres at
        // +0.5, so the disc centre in drawing coordinates is u / kTexel - 0.5.
        cv::circle(albedo,
                   cv::Point(static_cast<int>(std::lround((u / kTexel - 0.5) * 16)),
                             static_cast<int>(std::lround((v / kTexel - 0.5) * 16))),
                   static_cast<int>(0.03 / kTexel * 16), cv::Scalar(20), cv::FILLED, cv::LINE_AA,
                   4);
        disc_centers_world.push_back(wall.PointAt(u, v));
      }
    }
    world.textures.push_back(std::make_shared<const Texture>(albedo, kTexel));
    world.surfaces.push_back(wall);
  }
};

// The camera looks along world +y (camera x = world x, camera y = world -z), slightly turned.
Rigid3d CameraPose() {
  Eigen::Matrix3d world_from_cam;
  world_from_cam << 1, 0, 0,  //
      0, 0, 1,                //
      0, -1, 0;
  const Eigen::Quaterniond tilt = RotationFromRollPitchYaw(0.03, -0.02, 0.05);
  return Rigid3d(tilt * Eigen::Quaterniond(world_from_cam), Eigen::Vector3d(0.1, 0.0, 0.05));
}

// Centroid of darkness in a window around `guess`: weights = brightest - value.
Eigen::Vector2d DarkCentroid(const cv::Mat& radiance, const Eigen::Vector2d& guess, int half = 7) {
  const cv::Rect window(static_cast<int>(guess.x()) - half, static_cast<int>(guess.y()) - half,
                        2 * half + 1, 2 * half + 1);
  double brightest = 0;
  cv::minMaxLoc(radiance(window), nullptr, &brightest);
  double sum = 0, sx = 0, sy = 0;
  for (int r = window.y; r < window.y + window.height; ++r) {
    for (int c = window.x; c < window.x + window.width; ++c) {
      const double w = brightest - radiance.at<float>(r, c);
      sum += w;
      sx += w * c;
      sy += w * r;
    }
  }
  return Eigen::Vector2d(sx / sum, sy / sum);
}

class RendererProjectionTest : public ::testing::TestWithParam<bool> {};

TEST_P(RendererProjectionTest, RenderedPointLandsWhereTheCameraModelProjectsIt) {
  const bool distorted = GetParam();
  RigOptions rig_options;
  rig_options.distortion = distorted;
  const Camera camera = MakeRig(rig_options).left.camera;
  const DiscWall scene;
  const Renderer renderer(camera, /*supersample=*/2);
  const Rigid3d world_from_cam = CameraPose();
  const cv::Mat radiance = renderer.RenderRadiance(scene.world, world_from_cam, 0.0);
  int checked = 0;
  double worst_px = 0;
  for (const Eigen::Vector3d& center : scene.disc_centers_world) {
    Eigen::Vector2d expected;
    ASSERT_TRUE(camera.Project(world_from_cam.Inverse() * center, &expected));
    if (!camera.IsInImage(expected, 10)) continue;
    worst_px = std::max(worst_px, (DarkCentroid(radiance, expected) - expected).norm());
    ++checked;
  }
  EXPECT_GE(checked, 10);
  EXPECT_LT(worst_px, 0.2);  // required: 0.5 px
}

INSTANTIATE_TEST_SUITE_P(PinholeAndDistorted, RendererProjectionTest, ::testing::Bool());

TEST(RendererTest, StereoDisparityEqualsFocalTimesBaselineOverDepth) {
  const StereoRig rig = MakeRig(RigOptions{});
  const DiscWall scene;
  const Rigid3d world_from_left = CameraPose();
  const Rigid3d world_from_right =
      world_from_left * rig.left.body_from_cam.Inverse() * rig.right.body_from_cam;
  const double baseline = (world_from_right.translation - world_from_left.translation).norm();
  EXPECT_NEAR(baseline, 0.144, 1e-12);
  const cv::Mat left =
      Renderer(rig.left.camera, 2).RenderRadiance(scene.world, world_from_left, 0.0);
  const cv::Mat right =
      Renderer(rig.right.camera, 2).RenderRadiance(scene.world, world_from_right, 0.0);
  const double f = rig.left.camera.fx();
  int checked = 0;
  for (const Eigen::Vector3d& center : scene.disc_centers_world) {
    const Eigen::Vector3d in_left = world_from_left.Inverse() * center;
    Eigen::Vector2d left_px, right_px;
    ASSERT_TRUE(rig.left.camera.Project(in_left, &left_px));
    ASSERT_TRUE(rig.right.camera.Project(world_from_right.Inverse() * center, &right_px));
    if (!rig.left.camera.IsInImage(left_px, 10) || !rig.right.camera.IsInImage(right_px, 10))
      continue;
    const double disparity = DarkCentroid(left, left_px).x() - DarkCentroid(right, right_px).x();
    EXPECT_NEAR(disparity, f * baseline / in_left.z(), 0.5);
    ++checked;
  }
  EXPECT_GE(checked, 8);
}

TEST(RendererTest, DepthBufferKeepsTheNearestSurface) {
  DiscWall scene;
  // A 40 cm box face 1 m in front of the camera hides the wall behind it.
  Box box{{0.1, 1.2}, {0.4, 0.4, 2.0}, 0};
  AppendBoxFaces(box, &scene.world.surfaces);
  const Camera camera = Camera::FromHorizontalFov(320, 240, 90);
  Eigen::Matrix3d world_from_cam;
  world_from_cam << 1, 0, 0, 0, 0, 1, 0, -1, 0;
  cv::Mat depth;
  Renderer(camera, 1).RenderRadiance(
      scene.world, Rigid3d(world_from_cam, Eigen::Vector3d(0.1, 0, 1.0)), 0.0, &depth);
  EXPECT_NEAR(depth.at<float>(120, 160), 1.0, 1e-4);  // box face at y = 1.0
  EXPECT_NEAR(depth.at<float>(120, 40), 2.5, 1e-3);   // wall beside it (z-depth)
  EXPECT_EQ(depth.at<float>(120, 5), 0.0f);           // past the wall's edge: nothing
}

TEST_P(RendererProjectionTest, InsideAClosedRoomEveryPixelSeesASurface) {
  // Surfaces that reach far outside the field of view (floor, ceiling, side walls) must still
  // be drawn: a regression test for bounds computed through the distortion polynomial, which
  // folds points far outside the image back into it.
  RigOptions rig_options;
  rig_options.width = 160;
  rig_options.height = 120;
  rig_options.distortion = GetParam();
  RoomOptions room;
  room.texel_m = 0.02;
  const World world = MakeRoom(room);
  const StereoRig rig = MakeRig(rig_options);
  const Renderer renderer(rig.left.camera, 1);
  for (double yaw : {0.0, 0.8, 2.0, -2.5}) {
    const Rigid3d world_from_body(RotationFromRollPitchYaw(0.02, -0.05, yaw),
                                  Eigen::Vector3d(0.5, -0.3, 1.45));
    cv::Mat depth;
    renderer.RenderRadiance(world, world_from_body * rig.left.body_from_cam, 0.0, &depth);
    EXPECT_EQ(cv::countNonZero(depth > 0), depth.rows * depth.cols) << "yaw " << yaw;
  }
}

TEST(SensorModelTest, LowLightIsDarkerAndNoiseIsDeterministic) {
  const cv::Mat radiance(40, 40, CV_32FC1, cv::Scalar(0.5));
  SensorModel normal, dark;
  dark.exposure = 0.3;
  dark.gamma = 1.6;
  Rng a(5), b(5), c(5);
  const cv::Mat normal_image = normal.Capture(radiance, &a);
  EXPECT_NEAR(cv::mean(normal_image)[0], 127.5, 1.0);
  EXPECT_NEAR(cv::mean(dark.Capture(radiance, &b))[0], 255 * std::pow(0.15, 1 / 1.6), 1.0);
  EXPECT_EQ(cv::norm(normal_image, normal.Capture(radiance, &c), cv::NORM_INF), 0.0);
}

}  // namespace
}  // namespace visloc::sim
