// A job's spool read back as it was mapped, by the server that wrote it and by one that finds it
// after a crash: frames whose images or log line the crash cut short are not taken.

#include "server/job_spool.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "core/image/image_codec.h"
#include "core/util/check.h"
#include "core/util/temp_dir.h"
#include "proto/geometry_convert.h"

namespace visloc::server {
namespace {

using ::testing::HasSubstr;
namespace fs = std::filesystem;

class JobSpoolTest : public ::testing::Test {
 protected:
  JobSpoolTest() {
    start_.set_map_name("hall");
    start_.set_robot_id("robot");
    const Camera camera(64, 48, 60, 60, 31.5, 23.5);
    proto::ToProto(camera, start_.mutable_rig()->mutable_left());
    proto::ToProto(camera, start_.mutable_rig()->mutable_right());
    proto::ToProto(Rigid3d::Identity(), start_.mutable_rig()->mutable_body_from_left());
    proto::ToProto(Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.1, 0, 0)),
                   start_.mutable_rig()->mutable_body_from_right());
  }

  // A frame with random images: the left one sent as PNG bytes, the right one raw.
  v1::StereoFrame Frame(int64_t timestamp_ns, cv::Mat* left, cv::Mat* right) const {
    *left = cv::Mat(48, 64, CV_8UC1);
    *right = cv::Mat(48, 64, CV_8UC1);
    cv::randu(*left, 0, 255);
    cv::randu(*right, 0, 255);
    std::vector<uint8_t> png;
    std::string error;
    EXPECT_TRUE(image::EncodePng(*left, 1, &png, &error)) << error;
    v1::StereoFrame frame;
    frame.set_timestamp_ns(timestamp_ns);
    frame.set_left_encoded(std::string(png.begin(), png.end()));
    return frame;
  }

  TempDir root_{"visloc_job_spool"};
  v1::MappingStart start_;
  proto::WireLimits wire_;
};

TEST_F(JobSpoolTest, EncodedAndRawFramesReadBackAsMapped) {
  auto spool = JobSpool::Create(root_.path(), 3, start_, wire_);
  cv::Mat left, right;
  spool->Add(Frame(7, &left, &right), left, right);
  ASSERT_EQ(spool->size(), 1);
  EXPECT_EQ(spool->TimestampNs(0), 7);
  const mapping::StereoImages back = spool->Read(0);
  EXPECT_EQ(cv::norm(back.left_raw, left, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(back.right_raw, right, cv::NORM_INF), 0.0);
  EXPECT_EQ(back.timestamp_ns, 7);
  EXPECT_EQ(spool->name(), "robot");
  spool->Remove();
  EXPECT_FALSE(fs::exists(root_.File("3")));
}

TEST_F(JobSpoolTest, AReopenedJobHasItsStartFramesAndEndAndGoesOn) {
  cv::Mat left[3], right[3];
  {
    auto spool = JobSpool::Create(root_.path(), 12, start_, wire_);
    for (int i = 0; i < 2; ++i) spool->Add(Frame(100 + i, &left[i], &right[i]), left[i], right[i]);
    spool->MarkEnded();
  }  // The server dies here.
  EXPECT_EQ(JobSpool::JobIds(root_.path()), std::vector<uint64_t>{12});
  auto again = JobSpool::Open(root_.File("12"), wire_);
  EXPECT_EQ(again->job_id(), 12u);
  EXPECT_EQ(again->start().map_name(), "hall");
  EXPECT_NEAR(again->rig().right_from_left.translation.x(), -0.1, 1e-12);
  EXPECT_TRUE(again->ended());
  ASSERT_EQ(again->size(), 2);
  EXPECT_EQ(again->TimestampNs(1), 101);
  EXPECT_EQ(cv::norm(again->Read(1).right_raw, right[1], cv::NORM_INF), 0.0);
  again->Add(Frame(102, &left[2], &right[2]), left[2], right[2]);
  EXPECT_EQ(JobSpool::Open(root_.File("12"), wire_)->size(), 3);
}

TEST_F(JobSpoolTest, FramesACrashCutShortAreNotTaken) {
  cv::Mat left, right;
  {
    auto spool = JobSpool::Create(root_.path(), 5, start_, wire_);
    for (int i = 0; i < 3; ++i) spool->Add(Frame(i + 1, &left, &right), left, right);
  }
  // The last line torn mid-write: frame 3 was never answered.
  std::ofstream(root_.File("5/frames.log"), std::ios::app) << "3 4";
  EXPECT_EQ(JobSpool::Open(root_.File("5"), wire_)->size(), 3);
  // An image that never reached the disk ends the frames there.
  fs::remove(root_.File("5/1_right"));
  auto spool = JobSpool::Open(root_.File("5"), wire_);
  EXPECT_EQ(spool->size(), 1);
  EXPECT_FALSE(spool->ended());
  // The next frame is numbered after what was kept.
  spool->Add(Frame(9, &left, &right), left, right);
  EXPECT_EQ(JobSpool::Open(root_.File("5"), wire_)->TimestampNs(1), 9);
}

TEST_F(JobSpoolTest, AFolderThatIsNoJobIsRefusedByName) {
  fs::create_directories(root_.File("8"));
  EXPECT_THAT([&] { JobSpool::Open(root_.File("8"), wire_); },
              ::testing::ThrowsMessage<InputError>(HasSubstr("mapping job 8 ")));
  std::ofstream(root_.File("8/start.pb")) << "not a protobuf at all";
  EXPECT_THAT([&] { JobSpool::Open(root_.File("8"), wire_); },
              ::testing::ThrowsMessage<InputError>(HasSubstr("is not a mapping job's start")));
  fs::create_directories(root_.File("notes"));
  EXPECT_EQ(JobSpool::JobIds(root_.path()), std::vector<uint64_t>{8});
}

}  // namespace
}  // namespace visloc::server
