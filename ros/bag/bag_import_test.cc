#include "ros/bag/bag_import.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <random>

#include "core/util/check.h"
#include "dataset/euroc.h"
#include "ros/bag/cdr_test_writer.h"
#include "ros/bag/ros2_bag.h"
#include "ros/bag/ros2_bag_test_writer.h"

namespace visloc::bag {
namespace {

namespace fs = std::filesystem;

class BagImportTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("bag_import_test_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_ / "bag");
  }
  void TearDown() override { fs::remove_all(dir_); }

  // A stereo ROS 2 bag: 10 frames at 20 Hz, camera_info on both cameras, the right image of
  // frame 4 missing, frame 7's right image 1 ms late, odometry at 50 Hz.
  void WriteStereoBag() {
    testing::Ros2BagWriter bag((dir_ / "bag" / "bag_0.db3").string());
    std::mt19937 rng(3);
    const int64_t t0 = 1'700'000'000'000'000'000;
    for (int i = 0; i < 10; ++i) {
      const int64_t t = t0 + i * 50'000'000;
      cv::Mat left(48, 64, CV_8UC1), right(48, 64, CV_8UC1);
      cv::randu(left, 0, 255);
      cv::randu(right, 0, 255);
      bag.Write("/cam0/camera_info", "sensor_msgs/msg/CameraInfo", t,
                testing::Ros2CameraInfo(t, 64, 48, 60.0, 32.0, 24.0, {0.01, 0, 0, 0, 0}, 0.0));
      bag.Write("/cam1/camera_info", "sensor_msgs/msg/CameraInfo", t,
                testing::Ros2CameraInfo(t, 64, 48, 60.0, 32.0, 24.0, {0.01, 0, 0, 0, 0}, 0.11));
      bag.Write("/cam0/image_raw", "sensor_msgs/msg/Image", t, testing::Ros2Image(t, left, "cam0"));
      if (i != 4) {
        const int64_t tr = i == 7 ? t + 1'000'000 : t;
        bag.Write("/cam1/image_raw", "sensor_msgs/msg/Image", tr,
                  testing::Ros2Image(tr, right, "cam1"));
      }
    }
    for (int i = 0; i < 25; ++i) {
      const int64_t t = t0 + i * 20'000'000;
      const double xyz[3] = {0.01 * i, 0, 0}, q[4] = {0, 0, 0, 1};
      bag.Write("/odom", "nav_msgs/msg/Odometry", t, testing::Ros2Odometry(t, xyz, q));
    }
  }

  ImportOptions StereoOptions() const {
    ImportOptions options;
    options.left_topic = "/cam0/image_raw";
    options.right_topic = "/cam1/image_raw";
    options.odometry_topic = "/odom";
    return options;
  }

  std::string Out() const { return (dir_ / "out").string(); }

  fs::path dir_;
};

TEST_F(BagImportTest, Ros2StereoBagBecomesAnEurocSequence) {
  WriteStereoBag();
  auto reader = OpenRos2Bag((dir_ / "bag").string());
  const ImportStats stats = ImportBag(*reader, StereoOptions(), Out());
  EXPECT_EQ(stats.left_images, 10);
  EXPECT_EQ(stats.right_images, 9);
  EXPECT_EQ(stats.frames, 9);
  EXPECT_EQ(stats.pairing.unpaired_left, 1);
  EXPECT_EQ(stats.pairing.max_offset_ns, 1'000'000);
  EXPECT_EQ(stats.odometry_poses, 25);
  EXPECT_EQ(stats.camera_source, "camera_info");

  const Dataset dataset = ReadDataset(Out());
  ASSERT_TRUE(dataset.has_stereo());
  EXPECT_EQ(dataset.frames.size(), 9u);
  EXPECT_DOUBLE_EQ(dataset.left.camera.fx(), 60.0);
  EXPECT_NEAR(dataset.right_from_left().translation.x(), -0.11, 1e-12);
  EXPECT_NEAR(dataset.left.rate_hz, 20.0, 0.5);
  EXPECT_EQ(dataset.odom_from_cam.size(), 25u);
  EXPECT_FALSE(fs::exists(Out() + ".partial"));
}

TEST_F(BagImportTest, MissingTopicsAreNamedWithWhatTheBagHas) {
  WriteStereoBag();
  auto reader = OpenRos2Bag((dir_ / "bag").string());
  ImportOptions options = StereoOptions();
  options.right_topic = "/cam1/image";
  try {
    ImportBag(*reader, options, Out());
    FAIL();
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("--right /cam1/image: no such topic"), std::string::npos) << what;
    EXPECT_NE(what.find("/cam1/image_raw (sensor_msgs/msg/Image, 9)"), std::string::npos) << what;
  }
  options = StereoOptions();
  options.odometry_topic = "/cam0/image_raw";  // An image topic as odometry.
  options.right_topic = "";
  EXPECT_THROW(ImportBag(*reader, options, Out()), InputError);
  EXPECT_FALSE(fs::exists(Out()));
}

TEST_F(BagImportTest, ACorruptMessageLeavesNothingBehind) {
  WriteStereoBag();
  {
    testing::Ros2BagWriter more((dir_ / "bag" / "bag_1.db3").string());
    more.Write("/cam0/image_raw", "sensor_msgs/msg/Image", 2'000'000'000'000'000'000,
               std::string("\0\x01\0\0\x05", 5));
  }
  auto reader = OpenRos2Bag((dir_ / "bag").string());
  try {
    ImportBag(*reader, StereoOptions(), Out());
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("bag_1.db3: /cam0/image_raw message"), std::string::npos)
        << e.what();
  }
  EXPECT_FALSE(fs::exists(Out()));
  EXPECT_FALSE(fs::exists(Out() + ".partial"));
}

TEST_F(BagImportTest, RefusesAnOccupiedOutputFolderAndForeignFiles) {
  WriteStereoBag();
  fs::create_directories(Out());
  std::ofstream(Out() + "/keep.txt") << "mine";
  auto reader = OpenRos2Bag((dir_ / "bag").string());
  EXPECT_THROW(ImportBag(*reader, StereoOptions(), Out()), InputError);
  EXPECT_TRUE(fs::exists(Out() + "/keep.txt"));

  std::ofstream(dir_ / "notes.db3") << "not sqlite at all, just text";
  EXPECT_THROW(OpenRos2Bag((dir_ / "notes.db3").string()), InputError);
  std::ofstream(dir_ / "run.mcap") << "x";
  try {
    OpenRos2Bag((dir_ / "run.mcap").string());
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("MCAP bags are not supported"), std::string::npos);
  }
  EXPECT_THROW(OpenRos2Bag((dir_ / "missing").string()), NotFoundError);
}

TEST_F(BagImportTest, MonocularImportNeedsOnlyTheLeftCamera) {
  WriteStereoBag();
  auto reader = OpenRos2Bag((dir_ / "bag").string());
  ImportOptions options;
  options.left_topic = "/cam0/image_raw";
  const ImportStats stats = ImportBag(*reader, options, Out());
  EXPECT_EQ(stats.frames, 10);
  EXPECT_FALSE(ReadDataset(Out()).has_stereo());
}

TEST_F(BagImportTest, CameraInfoIsNotNeededWithSensorYaml) {
  WriteStereoBag();
  auto reader = OpenRos2Bag((dir_ / "bag").string());
  ImportOptions options = StereoOptions();
  options.left_info_topic = "/nothing/camera_info";
  try {
    ImportBag(*reader, options, Out());
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("give --left-yaml"), std::string::npos) << e.what();
  }
  CameraInfo left, right;
  left.camera = Camera(64, 48, 61, 61, 32, 24);
  right = left;
  right.body_from_cam.translation = Eigen::Vector3d(0.2, 0, 0);
  options.left_yaml = left;
  options.right_yaml = right;
  const ImportStats stats = ImportBag(*reader, options, Out());
  EXPECT_EQ(stats.camera_source, "sensor.yaml");
  EXPECT_NEAR(ReadDataset(Out()).right_from_left().translation.x(), -0.2, 1e-12);
}

}  // namespace
}  // namespace visloc::bag
