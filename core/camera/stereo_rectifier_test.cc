#include "core/camera/stereo_rectifier.h"

#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include "core/util/check.h"
#include "core/util/random.h"

namespace visloc {
namespace {

// A realistic, imperfect rig: different distortion per camera, a small relative rotation and a
// baseline that is not purely along x.
struct Rig {
  Camera left{640, 480, 400.0, 402.0, 322.0, 238.0, {-0.20, 0.05, 0.001, -0.0005}};
  Camera right{640, 480, 398.0, 399.0, 318.0, 244.0, {-0.18, 0.04, -0.0008, 0.0004}};
  Rigid3d right_from_left{RotationFromRollPitchYaw(0.01, -0.015, 0.008),
                          Eigen::Vector3d(-0.144, 0.003, -0.002)};
};

// Rows agree and depth follows from disparity, for ordinary and fisheye lenses.
void ExpectRowsAgree(const Rig& rig) {
  const StereoRectifier rectifier(rig.left, rig.right, rig.right_from_left);
  EXPECT_NEAR(rectifier.baseline_m(), rig.right_from_left.translation.norm(), 1e-9);
  Rng rng(3);
  int checked = 0;
  double worst_row_px = 0.0;
  double worst_depth_rel = 0.0;
  for (int i = 0; i < 500; ++i) {
    const Eigen::Vector3d point_in_left(rng.Uniform(-2, 2), rng.Uniform(-1.5, 1.5),
                                        rng.Uniform(1.0, 8.0));
    Eigen::Vector2d left_px, right_px;
    if (!rig.left.Project(point_in_left, &left_px) ||
        !rig.right.Project(rig.right_from_left * point_in_left, &right_px) ||
        !rig.left.IsInImage(left_px, 20) || !rig.right.IsInImage(right_px, 20)) {
      continue;
    }
    const Eigen::Vector2d left_rect = rectifier.RectifyLeftPixel(left_px);
    const Eigen::Vector2d right_rect = rectifier.RectifyRightPixel(right_px);
    if (!left_rect.allFinite() || !right_rect.allFinite()) continue;
    worst_row_px = std::max(worst_row_px, std::abs(left_rect.y() - right_rect.y()));
    // Depth from disparity (paper eq. 1) in the rectified frame.
    const double disparity = left_rect.x() - right_rect.x();
    const double depth_rect = (rectifier.rect_from_left() * point_in_left).z();
    const double depth_from_disparity =
        rectifier.rectified_camera().fx() * rectifier.baseline_m() / disparity;
    worst_depth_rel =
        std::max(worst_depth_rel, std::abs(depth_from_disparity - depth_rect) / depth_rect);
    ++checked;
  }
  EXPECT_GT(checked, 200);
  EXPECT_LT(worst_row_px, 0.1);
  EXPECT_LT(worst_depth_rel, 1e-6);
}

TEST(StereoRectifierTest, CorrespondingPointsShareARow) { ExpectRowsAgree(Rig{}); }

TEST(StereoRectifierTest, FisheyePointsShareARowToo) {
  Rig rig;
  rig.left = Camera(640, 480, 200.0, 201.0, 322.0, 238.0,
                    Lens::Equidistant(0.012, -0.004, 0.001, -0.0002));
  rig.right = Camera(640, 480, 199.0, 199.5, 318.0, 244.0,
                     Lens::Equidistant(0.010, -0.003, 0.0008, -0.0001));
  ExpectRowsAgree(rig);
}

TEST(StereoRectifierTest, RectifiedImagesAlignAFeatureOnOneRow) {
  const Rig rig;
  const StereoRectifier rectifier(rig.left, rig.right, rig.right_from_left);
  // Render a bright dot at a 3D point into both raw images, rectify, compare centroids.
  const Eigen::Vector3d point_in_left(0.3, 0.2, 3.0);
  Eigen::Vector2d left_px, right_px;
  ASSERT_TRUE(rig.left.Project(point_in_left, &left_px));
  ASSERT_TRUE(rig.right.Project(rig.right_from_left * point_in_left, &right_px));
  auto draw = [](const Eigen::Vector2d& center) {
    cv::Mat image(480, 640, CV_8UC1, cv::Scalar(0));
    cv::circle(image, cv::Point(cvRound(center.x() * 16), cvRound(center.y() * 16)), 4 * 16,
               cv::Scalar(255), cv::FILLED, cv::LINE_AA, 4);
    return image;
  };
  cv::Mat left_rect, right_rect;
  rectifier.Rectify(draw(left_px), draw(right_px), &left_rect, &right_rect);
  EXPECT_EQ(left_rect.size(), right_rect.size());
  const cv::Moments ml = cv::moments(left_rect);
  const cv::Moments mr = cv::moments(right_rect);
  EXPECT_NEAR(ml.m01 / ml.m00, mr.m01 / mr.m00, 0.1);
  EXPECT_THROW(rectifier.Rectify(cv::Mat(10, 10, CV_8UC1), cv::Mat(10, 10, CV_8UC1), &left_rect,
                                 &right_rect),
               CheckError);
}

TEST(StereoRectifierTest, SwappedOrVerticalRigsAreRefused) {
  const Rig rig;
  try {
    StereoRectifier(rig.right, rig.left, rig.right_from_left.Inverse());
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(),
                 "the right camera sits 0.144 m to the left of the left one: are the two cameras "
                 "swapped?");
  }
  EXPECT_THROW(StereoRectifier(rig.left, rig.right,
                               Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0.1, 0))),
               InputError);
}

TEST(StereoRectifierTest, TheCanvasKeepsTheCornersOfADistortedImage) {
  // Strong barrel distortion (EuRoC's k1 = -0.28): the region valid in both rectified views
  // loses the raw image's corners, where keypoints are; the canvas keeps them.
  const Camera left{752, 480, 458.7, 457.3, 367.2, 248.4, {-0.28, 0.07, 0.0, 0.0}};
  const Camera right{752, 480, 457.6, 456.1, 380.0, 255.2, {-0.28, 0.07, 0.0, 0.0}};
  const StereoRectifier rectifier(left, right, Rigid3d(RotationFromRollPitchYaw(0.0, 0.0, 0.0),
                                                       Eigen::Vector3d(-0.11, 0.0, 0.0)));
  const Eigen::Vector2d corner_raw(20.0, 20.0);
  const Eigen::Vector2d corner_rect = rectifier.RectifyLeftPixel(corner_raw);
  EXPECT_FALSE(rectifier.rectified_camera().IsInImage(corner_rect));
  const Eigen::Vector2d on_canvas = corner_rect + rectifier.canvas_offset_px();
  ASSERT_GT(on_canvas.x(), 0);
  ASSERT_GT(on_canvas.y(), 0);
  ASSERT_LT(on_canvas.x(), rectifier.canvas_size().width - 1);
  ASSERT_LT(on_canvas.y(), rectifier.canvas_size().height - 1);
  cv::Mat left_raw(480, 752, CV_8UC1, cv::Scalar(0));
  cv::circle(left_raw, cv::Point(20, 20), 3, cv::Scalar(255), cv::FILLED);
  cv::Mat left_rect, right_rect;
  rectifier.Rectify(left_raw, left_raw, &left_rect, &right_rect);
  EXPECT_EQ(left_rect.size(), rectifier.canvas_size());
  const cv::Moments m = cv::moments(left_rect);
  EXPECT_NEAR(m.m10 / m.m00, on_canvas.x(), 0.5);
  EXPECT_NEAR(m.m01 / m.m00, on_canvas.y(), 0.5);
}

}  // namespace
}  // namespace visloc
