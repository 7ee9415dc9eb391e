// A job's kept frames read back as they were mapped, whether they came encoded or raw.

#include "server/spooled_frames.h"

#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>

namespace visloc::server {
namespace {

TEST(SpooledFramesTest, EncodedAndRawFramesReadBackAsMapped) {
  const Camera camera(64, 48, 60, 60, 31.5, 23.5);
  SpooledFrames spool("robot", {camera, camera, Rigid3d::Identity()});
  cv::Mat left(48, 64, CV_8UC1), right(48, 64, CV_8UC1);
  cv::randu(left, 0, 255);
  cv::randu(right, 0, 255);
  std::vector<uchar> png;
  cv::imencode(".png", left, png);
  v1::StereoFrame encoded;  // The left image as PNG bytes, the right one raw.
  encoded.set_timestamp_ns(7);
  encoded.set_left_encoded(std::string(png.begin(), png.end()));
  spool.Add(encoded, left, right);
  ASSERT_EQ(spool.size(), 1);
  EXPECT_EQ(spool.TimestampNs(0), 7);
  const mapping::StereoImages back = spool.Read(0);
  EXPECT_EQ(cv::norm(back.left_raw, left, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(back.right_raw, right, cv::NORM_INF), 0.0);
  EXPECT_EQ(back.timestamp_ns, 7);
}

}  // namespace
}  // namespace visloc::server
