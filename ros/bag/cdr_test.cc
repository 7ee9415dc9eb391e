#include "ros/bag/cdr.h"

#include <gtest/gtest.h>

#include "core/util/check.h"
#include "ros/bag/cdr_test_writer.h"
#include "ros/bag/ros2_messages.h"

namespace visloc::bag {
namespace {

using testing::CdrWriter;

TEST(CdrReaderTest, ReadsAlignedFieldsBackInOrder) {
  CdrWriter w;
  w.U8(7).U32(123456).String("frame").F64(2.5).I32(-4);
  const std::string bytes = w.str();  // The reader views it: it must outlive the reader.
  CdrReader in(bytes);
  EXPECT_EQ(in.U8("a"), 7);
  EXPECT_EQ(in.U32("b"), 123456u);
  EXPECT_EQ(in.String("c"), "frame");
  EXPECT_DOUBLE_EQ(in.F64("d"), 2.5);
  EXPECT_EQ(in.I32("e"), -4);
  EXPECT_EQ(in.remaining(), 0u);
}

TEST(CdrReaderTest, ReadsBigEndianMessages) {
  const std::string be = std::string("\0\0\0\0", 4) + std::string("\0\0\x01\x02", 4);
  CdrReader in(be);
  EXPECT_EQ(in.U32("value"), 0x0102u);
}

TEST(CdrReaderTest, RefusesTruncatedMessagesNamingTheField) {
  CdrWriter w;
  w.String("a long frame id");
  const std::string bytes = w.str();
  const std::string truncated = bytes.substr(0, bytes.size() - 3);
  CdrReader in(truncated);
  try {
    in.String("header.frame_id");
    FAIL() << "read past the end";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("header.frame_id"), std::string::npos) << e.what();
  }
}

TEST(CdrReaderTest, RefusesForeignEncapsulationsAndHugeSequences) {
  EXPECT_THROW(CdrReader(std::string_view("\0\x03\0\0", 4)), InputError);  // XCDR2 / PL_CDR
  EXPECT_THROW(CdrReader(std::string_view("\0\x01", 2)), InputError);
  CdrWriter w;
  w.U32(0x40000000u);  // 1 G doubles claimed, none present.
  const std::string bytes = w.str();
  CdrReader in(bytes);
  EXPECT_THROW(in.F64Sequence("d"), InputError);
}

TEST(Ros2MessagesTest, DecodesImageCameraInfoAndOdometry) {
  cv::Mat grey(3, 5, CV_8UC1);
  for (int i = 0; i < 15; ++i) grey.data[i] = static_cast<uint8_t>(i * 10);
  const ros_msg::Message image =
      DecodeRos2Message("sensor_msgs/Image", testing::Ros2Image(1'500'000'123, grey, "cam0"));
  const auto& decoded = std::get<ros_msg::ImageMessage>(image);
  EXPECT_EQ(decoded.header.stamp_ns, 1'500'000'123);
  EXPECT_EQ(decoded.header.frame_id, "cam0");
  EXPECT_EQ(cv::norm(decoded.grey, grey, cv::NORM_INF), 0.0);

  const ros_msg::Message info = DecodeRos2Message(
      "sensor_msgs/CameraInfo",
      testing::Ros2CameraInfo(7, 320, 240, 250.0, 160.0, 120.0, {0.1, -0.01, 0, 0, 0}, 0.11));
  const auto& camera = std::get<ros_msg::CameraInfoMessage>(info);
  EXPECT_EQ(camera.width, 320);
  EXPECT_EQ(camera.distortion_model, "plumb_bob");
  ASSERT_EQ(camera.d.size(), 5u);
  EXPECT_DOUBLE_EQ(camera.d[0], 0.1);
  EXPECT_DOUBLE_EQ(camera.p[3], -250.0 * 0.11);

  const double xyz[3] = {1, 2, 3}, q[4] = {0, 0, 0.7071067811865476, 0.7071067811865476};
  const ros_msg::Message odom = DecodeRos2Message("nav_msgs/Odometry", testing::Ros2Odometry(9, xyz, q));
  const auto& o = std::get<ros_msg::OdometryMessage>(odom);
  EXPECT_EQ(o.child_frame_id, "base_link");
  EXPECT_NEAR((o.odom_from_child * Eigen::Vector3d(1, 0, 0) - Eigen::Vector3d(1, 3, 3)).norm(),
              0.0, 1e-12);
}

TEST(Ros2MessagesTest, EveryTruncationOfAMessageIsRefusedCleanly) {
  const std::string info =
      testing::Ros2CameraInfo(7, 320, 240, 250.0, 160.0, 120.0, {0, 0, 0, 0}, 0.0);
  // The last 25 bytes (binning and region of interest) are not read.
  for (size_t size = 0; size < info.size() - 25; ++size) {
    EXPECT_THROW(DecodeRos2Message("sensor_msgs/CameraInfo", info.substr(0, size)), InputError)
        << size;
  }
}

}  // namespace
}  // namespace visloc::bag
