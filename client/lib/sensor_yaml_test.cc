// The robot's sensor.yaml reader against the engine's: the same camera from every kind of file
// visloc writes and from real EuRoC calibrations, and errors that name the file and the key.

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include <google/protobuf/util/message_differencer.h>

#include "core/util/temp_dir.h"
#include "dataset/euroc.h"
#include "proto/convert.h"
#include "visloc/client/session.h"

namespace visloc::client {
namespace {

using ::testing::HasSubstr;

// What the engine reads from `path`, as the wire's camera.
v1::CameraModel EngineCamera(const std::string& path) {
  v1::CameraModel camera;
  proto::ToProto(ReadSensorYaml(path).camera, &camera);
  return camera;
}

void ExpectSameCamera(const std::string& path) {
  const v1::CameraModel robot = CameraFromYaml(path);
  const v1::CameraModel engine = EngineCamera(path);
  EXPECT_TRUE(google::protobuf::util::MessageDifferencer::Equals(robot, engine))
      << path << "\nrobot:  " << robot.ShortDebugString()
      << "\nengine: " << engine.ShortDebugString();
}

void WriteText(const std::string& path, const std::string& text) {
  std::ofstream(path) << text;
}

TEST(CameraFromYamlTest, ReadsWhatVislocWritesAsTheEngineDoes) {
  TempDir dir("visloc-sensor-yaml");
  CameraInfo info;
  info.rate_hz = 20;
  info.camera = Camera(752, 480, 458.654, 457.296, 367.215, 248.375);
  WriteSensorYaml(dir.File("ideal.yaml"), info, "ideal");
  info.camera = Camera(752, 480, 458.654, 457.296, 367.215, 248.375,
                       Lens(-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05));
  WriteSensorYaml(dir.File("radtan.yaml"), info, "radial-tangential");
  info.camera = Camera(640, 480, 190.1, 190.2, 320.5, 240.5,
                       Lens::Equidistant(0.0034, 0.0007, -0.0044, 0.0011));
  WriteSensorYaml(dir.File("fisheye.yaml"), info, "equidistant");
  for (const char* name : {"ideal.yaml", "radtan.yaml", "fisheye.yaml"}) {
    ExpectSameCamera(dir.File(name));
  }
  const v1::CameraModel fisheye = CameraFromYaml(dir.File("fisheye.yaml"));
  EXPECT_EQ(fisheye.lens_model(), v1::EQUIDISTANT);
  ASSERT_EQ(fisheye.distortion_size(), 4);
  EXPECT_DOUBLE_EQ(fisheye.distortion(2), -0.0044);
  EXPECT_EQ(fisheye.width(), 640u);
  EXPECT_DOUBLE_EQ(fisheye.fx(), 190.1);
}

TEST(CameraFromYamlTest, ARigCameraIsPlacedByItsT_BSAsTheEngineReadsIt) {
  TempDir dir("visloc-sensor-yaml");
  CameraInfo info;
  info.rate_hz = 20;
  info.camera = Camera(320, 240, 160, 160, 159.5, 119.5);
  for (const double yaw : {0.0, 0.3, M_PI, -2.0}) {
    info.body_from_cam = Rigid3d(RotationFromRollPitchYaw(0.2, -1.1, yaw), {-0.1, 0.02, 0.3});
    WriteSensorYaml(dir.File("rear.yaml"), info, "rear");
    const v1::RigCamera rig_camera = RigCameraFromYaml(dir.File("rear.yaml"), "rear");
    EXPECT_EQ(rig_camera.name(), "rear");
    ExpectSameCamera(dir.File("rear.yaml"));
    const Rigid3d robot = proto::FromProto(rig_camera.body_from_cam(), "body_from_cam");
    const Rigid3d engine = ReadSensorYaml(dir.File("rear.yaml")).body_from_cam;
    EXPECT_TRUE(ApproxEqual(robot, engine, 1e-12, 1e-9)) << "yaw " << yaw;
  }
  WriteText(
      dir.File("sheared.yaml"),
      "camera_model: pinhole\nresolution: [320, 240]\nintrinsics: [160, 160, 159.5, 119.5]\n"
      "T_BS:\n  cols: 4\n  rows: 4\n  data: [1, 0.5, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]\n");
  EXPECT_THAT([&] { RigCameraFromYaml(dir.File("sheared.yaml"), "x"); },
              ::testing::ThrowsMessage<std::invalid_argument>(
                  HasSubstr("sheared.yaml: T_BS is not a rigid transform")));
}

TEST(CameraFromYamlTest, ReadsRealEurocCalibrationsAsTheEngineDoes) {
  const std::string real = VISLOC_REAL_DATA;
  if (!std::filesystem::is_directory(real)) GTEST_SKIP() << "no real recordings at " << real;
  int files = 0;
  for (const auto& entry : std::filesystem::recursive_directory_iterator(real)) {
    if (entry.path().filename() != "sensor.yaml") continue;
    std::ifstream in(entry.path());
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (text.find("camera_model") == std::string::npos) continue;  // imu0
    ExpectSameCamera(entry.path().string());
    ++files;
  }
  if (files == 0) GTEST_SKIP() << "no camera sensor.yaml under " << real;
}

TEST(CameraFromYamlTest, ProblemsNameTheFileAndTheKey) {
  TempDir dir("visloc-sensor-yaml");
  const auto error = [&](const std::string& name, const std::string& text) -> std::string {
    if (!text.empty()) WriteText(dir.File(name), text);
    try {
      CameraFromYaml(dir.File(name));
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    return "no error";
  };
  EXPECT_THAT(error("absent.yaml", ""), HasSubstr("absent.yaml: no such file"));
  const std::string good =
      "camera_model: pinhole\nresolution: [320, 240]\nintrinsics: [160, 160, 159.5, 119.5]\n";
  EXPECT_THAT(error("no_model.yaml", "resolution: [320, 240]\n"),
              HasSubstr("no_model.yaml: missing 'camera_model'"));
  EXPECT_THAT(error("omni.yaml", "camera_model: omni\n"),
              HasSubstr("unsupported camera_model 'omni' (expected pinhole)"));
  EXPECT_THAT(error("short.yaml", "camera_model: pinhole\nresolution: [320, 240]\n"
                                  "intrinsics: [160, 160, 159.5]\n"),
              HasSubstr("short.yaml: 'intrinsics' must be a list of 4 numbers"));
  EXPECT_THAT(error("words.yaml", "camera_model: pinhole\nresolution: [wide, 240]\n"
                                  "intrinsics: [160, 160, 159.5, 119.5]\n"),
              HasSubstr("'resolution' has a non-number"));
  EXPECT_THAT(error("kb8.yaml", good + "distortion_model: kb8\n"),
              HasSubstr("unsupported distortion_model 'kb8'"));
  EXPECT_THAT(error("three.yaml", good + "distortion_model: equidistant\n"
                                         "distortion_coefficients: [0, 0, 0]\n"),
              HasSubstr("'distortion_coefficients' must be a list of 4 numbers"));
  EXPECT_THAT(error("garbage.yaml", "[: {\n\x01\x02"), HasSubstr("garbage.yaml: "));
  EXPECT_EQ(CameraFromYaml((WriteText(dir.File("good.yaml"), good), dir.File("good.yaml")))
                .distortion_size(),
            0);
}

}  // namespace
}  // namespace visloc::client
