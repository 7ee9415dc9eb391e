#include "dataset/kitti.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "core/util/check.h"
#include "core/util/temp_dir.h"

namespace visloc {
namespace {

using ::testing::HasSubstr;

void WriteSequence(const std::string& dir, int frames) {
  const Camera camera(64, 48, 40.0, 40.0, 31.5, 23.5);
  WriteKittiCalibration(dir, camera, 0.144);
  std::vector<int64_t> times;
  Trajectory poses;
  for (int i = 0; i < frames; ++i) {
    WriteKittiFrame(dir, i, cv::Mat(48, 64, CV_8UC1, cv::Scalar(i)),
                    cv::Mat(48, 64, CV_8UC1, cv::Scalar(200)));
    times.push_back(i * 100'000'000LL);
    poses.push_back({times.back(), Rigid3d(RotationFromRollPitchYaw(0, 0.05 * i, 0),
                                           Eigen::Vector3d(0, 0, 0.3 * i))});
  }
  WriteKittiTimesAndPoses(dir, times, poses);
}

TEST(KittiTest, WrittenSequenceReadsBack) {
  TempDir dir;
  WriteSequence(dir.path(), 4);
  const Dataset dataset = ReadDataset(dir.path());
  EXPECT_EQ(dataset.format, DatasetFormat::kKitti);
  ASSERT_EQ(dataset.frames.size(), 4u);
  EXPECT_EQ(dataset.frames[3].timestamp_ns, 300'000'000);
  EXPECT_NEAR(dataset.left.camera.fx(), 40.0, 1e-9);
  EXPECT_NEAR(dataset.left.rate_hz, 10.0, 1e-9);
  ASSERT_TRUE(dataset.has_stereo());
  EXPECT_TRUE(dataset.right_from_left().translation.isApprox(Eigen::Vector3d(-0.144, 0, 0), 1e-9));
  ASSERT_EQ(dataset.world_from_body.size(), 4u);
  EXPECT_NEAR(dataset.GroundTruthLeftCam()[2].pose.translation.z(), 0.6, 1e-9);
  EXPECT_EQ(LoadGreyImage(dataset.frames[2].left_path, 64, 48).at<uint8_t>(5, 5), 2);
}

TEST(KittiTest, CountMismatchAndBadCalibrationAreNamed) {
  TempDir dir;
  WriteSequence(dir.path(), 3);
  std::ofstream(dir.File("times.txt"), std::ios::app) << "0.9\n";
  EXPECT_THAT([&] { ReadDataset(dir.path()); },
              ::testing::ThrowsMessage<InputError>(
                  HasSubstr("image_0: 3 images but times.txt has 4 timestamps")));
  std::ofstream(dir.File("times.txt"), std::ios::trunc) << "0.0\n0.2\n0.1\n";
  EXPECT_THAT(
      [&] { ReadDataset(dir.path()); },
      ::testing::ThrowsMessage<InputError>(HasSubstr("times.txt:3: timestamps must increase")));
  std::ofstream(dir.File("times.txt"), std::ios::trunc) << "0.0\n0.1\n0.2\n";
  std::ofstream(dir.File("calib.txt"), std::ios::trunc) << "P0: 1 2 3\n";
  EXPECT_THAT([&] { ReadDataset(dir.path()); }, ::testing::ThrowsMessage<InputError>(HasSubstr(
                                                    "calib.txt:1: P0: needs 12 numbers, found 3")));
}

}  // namespace
}  // namespace visloc
