#include "ros/messages/ros_messages.h"

#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include "core/image/image_codec.h"
#include "core/util/check.h"

namespace visloc::ros_msg {
namespace {

std::string_view View(const cv::Mat& m) {
  return std::string_view(reinterpret_cast<const char*>(m.data), m.total() * m.elemSize());
}

TEST(DecodeRawImageTest, ConvertsEncodingsToGrey) {
  cv::Mat bgr(4, 6, CV_8UC3, cv::Scalar(10, 20, 30));
  const cv::Mat from_bgr = DecodeRawImage(6, 4, "bgr8", false, 18, View(bgr));
  cv::Mat expected;
  cv::cvtColor(bgr, expected, cv::COLOR_BGR2GRAY);
  EXPECT_EQ(cv::norm(from_bgr, expected, cv::NORM_INF), 0.0);
  // rgb8 of the same bytes reads the channels the other way round.
  const cv::Mat from_rgb = DecodeRawImage(6, 4, "rgb8", false, 18, View(bgr));
  EXPECT_NE(from_rgb.at<uint8_t>(0, 0), from_bgr.at<uint8_t>(0, 0));

  cv::Mat wide(2, 3, CV_16UC1, cv::Scalar(0x1234));
  EXPECT_EQ(DecodeRawImage(3, 2, "mono16", false, 6, View(wide)).at<uint8_t>(1, 2), 0x12);
  // Big-endian 16-bit bytes: 0x1234 is stored 0x12 0x34.
  cv::Mat swapped(2, 3, CV_16UC1, cv::Scalar(0x3412));
  EXPECT_EQ(DecodeRawImage(3, 2, "16UC1", true, 6, View(swapped)).at<uint8_t>(0, 0), 0x12);
}

TEST(DecodeRawImageTest, HonoursRowPadding) {
  cv::Mat padded(3, 8, CV_8UC1, cv::Scalar(0));
  padded(cv::Rect(0, 0, 5, 3)).setTo(200);
  const cv::Mat grey = DecodeRawImage(5, 3, "mono8", false, 8, View(padded));
  EXPECT_EQ(grey.cols, 5);
  EXPECT_EQ(cv::countNonZero(grey == 200), 15);
}

TEST(DecodeRawImageTest, ReadsSixteenBitRowsWithAnOddStep) {
  // Found by the ros2_message fuzzer: a step that is not a multiple of the pixel size made
  // cv::Mat throw its own exception instead of reading the rows.
  std::string bytes(5 * 2 + 7, '\0');
  for (int y = 0; y < 2; ++y) {
    for (int x = 0; x < 3; ++x) bytes[y * 7 + 2 * x + 1] = static_cast<char>(10 * (y * 3 + x));
  }
  const cv::Mat grey = DecodeRawImage(3, 2, "mono16", false, 7, bytes);
  EXPECT_EQ(grey.at<uint8_t>(1, 2), 50);
}

TEST(DecodeRawImageTest, RefusesWhatCannotBeAnImage) {
  cv::Mat grey(4, 4, CV_8UC1, cv::Scalar(1));
  EXPECT_THROW(DecodeRawImage(4, 4, "yuv422", false, 8, View(grey)), InputError);
  EXPECT_THROW(DecodeRawImage(4, 4, "mono8", false, 3, View(grey)), InputError);  // step < row
  EXPECT_THROW(DecodeRawImage(4, 5, "mono8", false, 4, View(grey)), InputError);  // too short
  EXPECT_THROW(DecodeRawImage(0, 4, "mono8", false, 4, View(grey)), InputError);
  try {
    DecodeRawImage(4, 4, "bgr8", false, 12, View(grey));
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("needs 48"), std::string::npos) << e.what();
  }
}

TEST(DecodeCompressedImageTest, DecodesJpegAndPngAndRefusesGarbage) {
  cv::Mat grey(16, 16, CV_8UC1, cv::Scalar(90));
  std::vector<uint8_t> png;
  std::string error;
  ASSERT_TRUE(image::EncodePng(grey, 1, &png, &error)) << error;
  const cv::Mat decoded = DecodeCompressedImage(
      "png", std::string_view(reinterpret_cast<char*>(png.data()), png.size()));
  EXPECT_EQ(cv::norm(decoded, grey, cv::NORM_INF), 0.0);
  EXPECT_THROW(DecodeCompressedImage("jpeg", "not a jpeg"), InputError);
  EXPECT_THROW(DecodeCompressedImage("jpeg", ""), InputError);
}

CameraInfoMessage Info(const std::string& model, std::vector<double> d) {
  CameraInfoMessage info;
  info.width = 640;
  info.height = 480;
  info.distortion_model = model;
  info.d = std::move(d);
  info.k = {500, 0, 320, 0, 500, 240, 0, 0, 1};
  info.r = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  info.p = {500, 0, 320, 0, 0, 500, 240, 0, 0, 0, 1, 0};
  return info;
}

TEST(CameraFromInfoTest, PlumbBobAndEquidistantBecomeVislocLenses) {
  const Camera pinhole = CameraFromInfo(Info("plumb_bob", {-0.28, 0.07, 1e-4, -2e-4, 0.0}), "/c");
  EXPECT_EQ(pinhole.lens().model, LensModel::kRadialTangential);
  EXPECT_DOUBLE_EQ(pinhole.lens().coefficients[1], 0.07);
  EXPECT_DOUBLE_EQ(pinhole.fx(), 500);
  const Camera fisheye = CameraFromInfo(Info("equidistant", {0.01, -0.002, 0.001, 0.0}), "/c");
  EXPECT_EQ(fisheye.lens().model, LensModel::kEquidistant);
}

TEST(CameraFromInfoTest, RefusesWhatVislocCannotModel) {
  // A k3 that moves the corner by pixels is not silently dropped; a tiny one is.
  EXPECT_THROW(CameraFromInfo(Info("plumb_bob", {-0.28, 0.07, 0, 0, 0.05}), "/c"), InputError);
  EXPECT_NO_THROW(CameraFromInfo(Info("plumb_bob", {-0.28, 0.07, 0, 0, 1e-6}), "/c"));
  EXPECT_THROW(CameraFromInfo(Info("fov", {0.9}), "/c"), InputError);
  CameraInfoMessage uncalibrated = Info("plumb_bob", {0, 0, 0, 0, 0});
  uncalibrated.k = {};
  try {
    CameraFromInfo(uncalibrated, "/cam0/camera_info");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("/cam0/camera_info"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("not calibrated"), std::string::npos);
  }
}

TEST(LeftFromRightTest, RecoversTheRigFromRectifiedProjections) {
  CameraInfoMessage left = Info("plumb_bob", {0, 0, 0, 0, 0});
  CameraInfoMessage right = left;
  // Both cameras turned by 2 degrees about y into the rectified frame, baseline 0.12 m.
  const Eigen::Matrix3d rect_from_left =
      Eigen::AngleAxisd(0.02, Eigen::Vector3d::UnitY()).toRotationMatrix();
  const Eigen::Matrix3d rect_from_right =
      Eigen::AngleAxisd(-0.01, Eigen::Vector3d::UnitY()).toRotationMatrix();
  for (int i = 0; i < 9; ++i) {
    left.r[i] = rect_from_left(i / 3, i % 3);
    right.r[i] = rect_from_right(i / 3, i % 3);
  }
  right.p[3] = -500 * 0.12;
  const Rigid3d left_from_right = LeftFromRight(left, right);
  // The right camera's centre is 0.12 m along the rectified x axis from the left one's.
  EXPECT_NEAR((rect_from_left * left_from_right.translation - Eigen::Vector3d(0.12, 0, 0)).norm(),
              0.0, 1e-12);
  EXPECT_NEAR(Eigen::AngleAxisd(left_from_right.rotation).angle(), 0.03, 1e-12);
  right.p[3] = 0;
  EXPECT_THROW(LeftFromRight(left, right), InputError);
  right.p[3] = 500 * 0.12;  // The "right" camera on the left: swapped topics.
  EXPECT_THROW(LeftFromRight(left, right), InputError);
}

}  // namespace
}  // namespace visloc::ros_msg
