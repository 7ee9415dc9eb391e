#include "sim/generate.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>

#include "core/util/check.h"
#include "core/util/temp_dir.h"
#include "core/util/text_file.h"
#include "dataset/tum.h"

namespace visloc::sim {
namespace {

GenerateOptions SmallOptions(int frames) {
  GenerateOptions options;
  options.rig.width = 160;
  options.rig.height = 120;
  options.supersample = 1;
  options.max_frames = frames;
  return options;
}

TEST(GenerateTest, WrittenSequenceReadsBackWithItsGroundTruth) {
  TempDir dir;
  SequenceGenerator generator(SmallOptions(6));
  const GenerateStats stats = generator.Generate("map_square", dir.path());
  EXPECT_EQ(stats.frames, 6);
  const Dataset dataset = ReadDataset(stats.dir);
  ASSERT_EQ(dataset.frames.size(), 6u);
  ASSERT_TRUE(dataset.has_stereo());
  const StereoRig rig = MakeRig(SmallOptions(6).rig);
  EXPECT_EQ(dataset.left.camera.Params(), rig.left.camera.Params());
  EXPECT_TRUE(ApproxEqual(dataset.left.body_from_cam, rig.left.body_from_cam, 1e-15, 1e-9));
  EXPECT_TRUE(dataset.right_from_left().translation.isApprox(Eigen::Vector3d(-0.144, 0, 0), 1e-12));
  EXPECT_EQ(dataset.frames[1].timestamp_ns - dataset.frames[0].timestamp_ns, 66'666'667);
  EXPECT_EQ(dataset.odom_from_cam.size(), 6u);
  EXPECT_FALSE(dataset.imu.empty());
  EXPECT_LE(dataset.imu.back().timestamp_ns, dataset.frames.back().timestamp_ns);
  LoadGreyImage(dataset.frames[5].right_path, 160, 120);

  // The map frame is the first left camera of map_square, and the TUM ground truth agrees with
  // the EuRoC ground truth composed with the camera extrinsics.
  const Trajectory map_from_cam = ReadTum(stats.dir + "/groundtruth_map.tum");
  ASSERT_EQ(map_from_cam.size(), 6u);
  EXPECT_TRUE(ApproxEqual(map_from_cam[0].pose, Rigid3d::Identity(), 1e-9, 1e-6));
  const Trajectory world_from_cam = dataset.GroundTruthLeftCam();
  for (size_t i = 0; i < 6; ++i) {
    const Rigid3d expected = world_from_cam[0].pose.Inverse() * world_from_cam[i].pose;
    EXPECT_TRUE(ApproxEqual(map_from_cam[i].pose, expected, 1e-8, 1e-6)) << i;
  }
  EXPECT_TRUE(std::filesystem::exists(stats.dir + "/contact_sheet.png"));
  // Dead reckoning starts at the true first pose.
  const Trajectory odometry_in_map = ReadTum(stats.dir + "/odometry_map.tum");
  ASSERT_EQ(odometry_in_map.size(), 6u);
  EXPECT_TRUE(ApproxEqual(odometry_in_map[0].pose, map_from_cam[0].pose, 1e-8, 1e-6));
  EXPECT_TRUE(ApproxEqual(odometry_in_map[5].pose, map_from_cam[5].pose, 0.05, 2.0));
}

TEST(GenerateTest, KidnapFramesAreCoveredAndListed) {
  TempDir dir;
  SequenceGenerator generator(SmallOptions(0));
  GenerateOptions options = SmallOptions(0);
  const SequenceSpec spec = MakeSequenceSpec("kidnap", 1);
  const int first_covered = static_cast<int>(std::ceil(spec.covered_s[0].first * 15));
  options.max_frames = first_covered + 3;
  const GenerateStats stats = SequenceGenerator(options).Generate("kidnap", dir.path());
  EXPECT_EQ(stats.covered_frames, 3);
  const Dataset dataset = ReadDataset(stats.dir);
  const cv::Mat covered = LoadGreyImage(dataset.frames.back().left_path, 160, 120);
  const cv::Mat open = LoadGreyImage(dataset.frames.front().left_path, 160, 120);
  EXPECT_LT(cv::mean(covered)[0], 10.0);
  EXPECT_GT(cv::mean(open)[0], 60.0);
  const auto lines = ReadTextLines(stats.dir + "/sequence.json");
  EXPECT_NE(lines[0].text.find("\"covered_frames\":[" + std::to_string(first_covered) + ","),
            std::string::npos);
}

TEST(GenerateTest, ARigsRearCameraSeesTheRoomWhileTheFrontPairIsCovered) {
  TempDir dir;
  GenerateOptions options = SmallOptions(0);
  options.rig.layout = RigOptions::Layout::kFour;
  const SequenceSpec spec = MakeSequenceSpec("kidnap", 1);
  options.max_frames = static_cast<int>(std::ceil(spec.covered_s[0].first * 15)) + 2;
  const GenerateStats stats = SequenceGenerator(options).Generate("kidnap", dir.path());
  const Dataset dataset = ReadDataset(stats.dir);
  ASSERT_EQ(dataset.other_cameras.size(), 3u);
  EXPECT_EQ(dataset.other_cameras[0].name, "cam2");
  EXPECT_EQ(dataset.other_cameras[2].name, "cam4");
  // The rear camera looks back along the body's x axis: its optical axis against the front's.
  const Eigen::Vector3d front_axis = dataset.left.body_from_cam.rotation * Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d rear_axis =
      dataset.other_cameras[0].info.body_from_cam.rotation * Eigen::Vector3d::UnitZ();
  EXPECT_NEAR(front_axis.dot(rear_axis), -1.0, 1e-12);
  const Eigen::Vector3d left_axis =
      dataset.other_cameras[1].info.body_from_cam.rotation * Eigen::Vector3d::UnitZ();
  EXPECT_NEAR(front_axis.dot(left_axis), 0.0, 1e-12);
  EXPECT_NEAR(left_axis.y(), 1.0, 1e-12);  // The body's left.
  for (const CameraStream& stream : dataset.other_cameras) {
    ASSERT_EQ(stream.images.size(), dataset.frames.size());
    EXPECT_EQ(stream.images.back().first, dataset.frames.back().timestamp_ns);
  }
  // The last frame is covered in front, not behind.
  EXPECT_LT(cv::mean(LoadGreyImage(dataset.frames.back().left_path, 160, 120))[0], 10.0);
  EXPECT_GT(cv::mean(LoadGreyImage(dataset.other_cameras[0].images.back().second, 160, 120))[0],
            40.0);
  const auto lines = ReadTextLines(stats.dir + "/sequence.json");
  EXPECT_NE(lines[0].text.find("\"rig\":\"four\""), std::string::npos);
  EXPECT_THROW(ParseRigLayout("three"), InputError);
}

TEST(GenerateTest, KittiLayoutReadsBack) {
  TempDir dir;
  GenerateOptions options = SmallOptions(4);
  options.format = DatasetFormat::kKitti;
  const GenerateStats stats = SequenceGenerator(options).Generate("straight", dir.path());
  const Dataset dataset = ReadDataset(stats.dir);
  EXPECT_EQ(dataset.format, DatasetFormat::kKitti);
  ASSERT_EQ(dataset.frames.size(), 4u);
  EXPECT_NEAR(dataset.right_from_left().translation.x(), -0.144, 1e-9);
  ASSERT_EQ(dataset.world_from_body.size(), 4u);
  EXPECT_TRUE(ApproxEqual(dataset.world_from_body[0].pose, Rigid3d::Identity(), 1e-9, 1e-6));
}

// A sequence cut short by max_frames reports the part it rendered, not the whole walk: 30 frames
// of `straight` (2 s at 15 Hz of a 3 m, 14 s walk) once said "14.0 s, 3.00 m".
TEST(GenerateTest, ACutSequenceReportsTheDurationAndPathItRendered) {
  TempDir dir;
  SequenceGenerator generator(SmallOptions(30));
  const GenerateStats stats = generator.Generate("straight", dir.path());
  EXPECT_EQ(stats.frames, 30);
  EXPECT_NEAR(stats.duration_s, 29 / 15.0, 1e-9);
  const Trajectory truth = ReadTum(stats.dir + "/groundtruth_map.tum");
  const double walked_m = (truth.back().pose.translation - truth.front().pose.translation).norm();
  EXPECT_NEAR(stats.path_length_m, walked_m, 0.01);  // A straight walk: the chord.
  EXPECT_LT(stats.path_length_m, 0.5);
}

TEST(GenerateTest, UnknownSequenceIsNamed) {
  TempDir dir;
  SequenceGenerator generator(SmallOptions(1));
  EXPECT_THAT([&] { generator.Generate("squre", dir.path()); },
              ::testing::ThrowsMessage<InputError>(
                  ::testing::HasSubstr("unknown sequence 'squre' (known: map_square")));
}

}  // namespace
}  // namespace visloc::sim
