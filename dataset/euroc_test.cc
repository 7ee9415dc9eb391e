#include "dataset/euroc.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "core/util/check.h"
#include "core/util/temp_dir.h"
#include "core/util/text_file.h"

namespace visloc {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

CameraInfo LeftCamera() {
  CameraInfo info;
  info.camera = Camera(64, 48, 40.5, 40.25, 31.5, 23.5, {-0.1, 0.01, 0.001, -0.002});
  info.body_from_cam =
      Rigid3d(RotationFromRollPitchYaw(-M_PI / 2, 0, -M_PI / 2), Eigen::Vector3d(0.0, 0.072, 0.0));
  info.rate_hz = 15;
  return info;
}

CameraInfo RightCamera() {
  CameraInfo info = LeftCamera();
  info.body_from_cam.translation = Eigen::Vector3d(0.0, -0.072, 0.0);
  return info;
}

cv::Mat Pattern(int seed) {
  cv::Mat image(48, 64, CV_8UC1);
  for (int r = 0; r < image.rows; ++r) {
    for (int c = 0; c < image.cols; ++c)
      image.at<uint8_t>(r, c) = (r * 7 + c * 3 + seed * 11) % 256;
  }
  return image;
}

// Writes a 5-frame stereo sequence with every optional stream.
void WriteSequence(const std::string& dir) {
  EurocWriter writer(dir, LeftCamera(), RightCamera());
  std::vector<ImuSample> imu;
  Trajectory odom, gt;
  for (int i = 0; i < 5; ++i) {
    const int64_t t = 1'000'000'000 + i * 66'666'667LL;
    writer.AddFrame(t, Pattern(i), Pattern(i + 100));
    odom.push_back(
        {t, Rigid3d(RotationFromRollPitchYaw(0, 0, 0.1 * i), Eigen::Vector3d(0.01 * i, 0, 0))});
    gt.push_back({t, Rigid3d(RotationFromRollPitchYaw(0.01, 0.02, 0.1 * i),
                             Eigen::Vector3d(0.011 * i, 0.002, 1.45))});
  }
  for (int k = 0; k < 60; ++k) {
    imu.push_back({1'000'000'000 + k * 5'000'000LL, Eigen::Vector3d(0.01, -0.02, 0.3),
                   Eigen::Vector3d(0.1, 0.2, 9.81)});
  }
  writer.Finish(imu, odom, gt);
}

std::string ExpectReadError(const std::string& dir) {
  try {
    ReadDataset(dir);
  } catch (const InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << "expected an InputError for " << dir;
  return "";
}

void ReplaceLine(const std::string& path, int line_number, const std::string& text) {
  auto lines = ReadTextLines(path);
  std::string out;
  for (const auto& line : lines) out += (line.number == line_number ? text : line.text) + "\n";
  std::ofstream(path) << out;
}

TEST(EurocTest, WrittenDatasetReadsBackIdentically) {
  TempDir dir;
  WriteSequence(dir.path());
  const Dataset dataset = ReadDataset(dir.path());
  EXPECT_EQ(dataset.format, DatasetFormat::kEuroc);
  ASSERT_TRUE(dataset.has_stereo());
  EXPECT_EQ(dataset.left.camera.Params(), LeftCamera().camera.Params());
  EXPECT_EQ(dataset.left.camera.width(), 64);
  EXPECT_DOUBLE_EQ(dataset.left.rate_hz, 15.0);
  EXPECT_TRUE(ApproxEqual(dataset.left.body_from_cam, LeftCamera().body_from_cam, 1e-15, 1e-9));
  EXPECT_TRUE(dataset.right_from_left().translation.isApprox(Eigen::Vector3d(-0.144, 0, 0), 1e-12));
  ASSERT_EQ(dataset.frames.size(), 5u);
  EXPECT_EQ(dataset.frames[3].timestamp_ns, 1'000'000'000 + 3 * 66'666'667LL);
  const cv::Mat left = LoadGreyImage(dataset.frames[3].left_path, 64, 48);
  const cv::Mat right = LoadGreyImage(dataset.frames[3].right_path, 64, 48);
  EXPECT_EQ(cv::norm(left, Pattern(3), cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(right, Pattern(103), cv::NORM_INF), 0.0);
  ASSERT_EQ(dataset.imu.size(), 60u);
  EXPECT_EQ(dataset.imu[59].timestamp_ns, 1'000'000'000 + 59 * 5'000'000LL);
  EXPECT_DOUBLE_EQ(dataset.imu[7].accel_mps2.z(), 9.81);
  ASSERT_EQ(dataset.odom_from_cam.size(), 5u);
  EXPECT_TRUE(ApproxEqual(dataset.odom_from_cam[4].pose,
                          Rigid3d(RotationFromRollPitchYaw(0, 0, 0.4), Eigen::Vector3d(0.04, 0, 0)),
                          1e-11, 1e-9));
  ASSERT_EQ(dataset.world_from_body.size(), 5u);
  EXPECT_TRUE(dataset.world_from_body[2].pose.translation.isApprox(
      Eigen::Vector3d(0.022, 0.002, 1.45), 1e-11));
  const Trajectory gt_cam = dataset.GroundTruthLeftCam();
  ASSERT_EQ(gt_cam.size(), 5u);
  EXPECT_TRUE(ApproxEqual(
      gt_cam[1].pose, dataset.world_from_body[1].pose * LeftCamera().body_from_cam, 1e-12, 1e-9));
}

TEST(EurocTest, MissingFolderIsNamed) {
  TempDir dir;
  EXPECT_THAT(ExpectReadError(dir.path() + "/nope"), HasSubstr("no such dataset directory"));
  EXPECT_THAT(ExpectReadError(dir.path()), HasSubstr("neither an EuRoC dataset"));
  fs::create_directories(dir.path() + "/mav0");
  EXPECT_THAT(ExpectReadError(dir.path()), HasSubstr("mav0/cam0: no such folder"));
}

TEST(EurocTest, BadCsvRowNamesFileAndLine) {
  TempDir dir;
  WriteSequence(dir.path());
  const std::string csv = dir.path() + "/mav0/imu0/data.csv";
  ReplaceLine(csv, 4, "1010000000,0.1,zero,0.3,0.1,0.2,9.8");
  EXPECT_EQ(ExpectReadError(dir.path()), csv + ":4: field 3 is not a number: 'zero'");
  ReplaceLine(csv, 4, "1010000000,0.1");
  EXPECT_EQ(ExpectReadError(dir.path()), csv + ":4: expected 7 fields, found 2");
}

TEST(EurocTest, ImagesArePairedByTimeAndUnpairedOnesCounted) {
  TempDir dir;
  WriteSequence(dir.path());
  // cam1 lost its last image and stamps the others 1 ms late; cam0 lost its second.
  const std::string csv = dir.path() + "/mav0/cam1/data.csv";
  auto lines = ReadTextLines(csv);
  std::string out = lines[0].text + "\n";
  for (size_t i = 1; i + 1 < lines.size(); ++i) {
    const std::string& text = lines[i].text;
    const int64_t t = std::stoll(text.substr(0, text.find(',')));
    out += std::to_string(t + 1'000'000) + text.substr(text.find(',')) + "\n";
  }
  std::ofstream(csv) << out;
  const std::string cam0 = dir.path() + "/mav0/cam0/data.csv";
  lines = ReadTextLines(cam0);
  out.clear();
  for (size_t i = 0; i < lines.size(); ++i) {
    if (i != 2) out += lines[i].text + "\n";
  }
  std::ofstream(cam0) << out;
  const Dataset dataset = ReadDataset(dir.path());
  EXPECT_EQ(dataset.frames.size(), 3u);  // 5 frames, less cam0's second and cam1's last
  EXPECT_EQ(dataset.pairing.unpaired_left, 1);
  EXPECT_EQ(dataset.pairing.unpaired_right, 1);
  EXPECT_EQ(dataset.pairing.max_offset_ns, 1'000'000);
  // Nothing within the tolerance: a clear refusal.
  lines = ReadTextLines(csv);
  out = lines[0].text + "\n";
  for (size_t i = 1; i < lines.size(); ++i) {
    const std::string& text = lines[i].text;
    const int64_t t = std::stoll(text.substr(0, text.find(',')));
    out += std::to_string(t + 10'000'000) + text.substr(text.find(',')) + "\n";
  }
  std::ofstream(csv) << out;
  EXPECT_THAT(ExpectReadError(dir.path()), HasSubstr("no cam0 image has a cam1 image within 2 ms"));
}

TEST(EurocTest, NonMonotonicTimestampsNameTheLine) {
  TempDir dir;
  WriteSequence(dir.path());
  const std::string gt = dir.path() + "/mav0/state_groundtruth_estimate0/data.csv";
  ReplaceLine(gt, 3, "900000000,0,0,1.45,1,0,0,0");
  EXPECT_THAT(ExpectReadError(dir.path()),
              HasSubstr(gt + ":3: timestamp 900000000 does not increase"));
}

TEST(EurocTest, MissingAndUnreadableImagesAreNamed) {
  TempDir dir;
  WriteSequence(dir.path());
  const Dataset dataset = ReadDataset(dir.path());
  // Corrupt one image: the read succeeds (files exist), decoding names the file.
  std::ofstream(dataset.frames[2].left_path, std::ios::trunc) << "not a png";
  try {
    LoadGreyImage(dataset.frames[2].left_path, 64, 48);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()),
              dataset.frames[2].left_path + ": not a PNG or JPEG image (first bytes 6e 6f 74 20)");
  }
  EXPECT_THAT([&] { LoadGreyImage(dataset.frames[1].left_path, 640, 480); },
              ::testing::ThrowsMessage<InputError>(
                  HasSubstr("image is 64x48 but the calibration says 640x480")));
  fs::remove(dataset.frames[4].right_path);
  EXPECT_THAT(ExpectReadError(dir.path()), HasSubstr("cam1/data.csv:6: missing image"));
}

TEST(EurocTest, BadCalibrationIsNamed) {
  TempDir dir;
  WriteSequence(dir.path());
  const std::string yaml = dir.path() + "/mav0/cam0/sensor.yaml";
  auto lines = ReadTextLines(yaml);
  std::string out;
  for (const auto& line : lines) {
    out += (line.text.rfind("camera_model", 0) == 0 ? "camera_model: omni" : line.text) + "\n";
  }
  std::ofstream(yaml) << out;
  EXPECT_THAT(ExpectReadError(dir.path()), HasSubstr("unsupported camera_model 'omni'"));
  std::ofstream(yaml) << "resolution: [64, 48\nintrinsics: [1, 2]\n";
  EXPECT_THAT(ExpectReadError(dir.path()), HasSubstr(yaml + ":"));
}

}  // namespace
}  // namespace visloc
