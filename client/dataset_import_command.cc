// `visloc dataset import`: a ROS bag (ROS 1 .bag through Debian's rosbag library, ROS 2 sqlite3
// bag folder or .db3 through our reader) becomes an EuRoC-layout sequence (ros/bag/).

#include <cstdio>
#include <iostream>
#include <sstream>

#include "client/commands.h"
#include "core/util/args.h"
#include "core/util/check.h"
#include "core/util/json.h"
#include "dataset/euroc.h"
#include "ros/bag/bag_import.h"
#include "ros/bag/ros2_bag.h"
#ifdef VISLOC_HAVE_ROS1
#include "ros/rosbag1/rosbag1_reader.h"
#endif

namespace visloc::cli {
namespace {

bool EndsWith(const std::string& text, const std::string& suffix) {
  return text.size() >= suffix.size() &&
         text.compare(text.size() - suffix.size(), suffix.size(), suffix) == 0;
}

std::unique_ptr<bag::BagReader> OpenBag(const std::string& path) {
  if (EndsWith(path, ".bag")) {
#ifdef VISLOC_HAVE_ROS1
    return bag::OpenRos1Bag(path);
#else
    throw InputError(StrCat(path, ": this visloc was built without ROS 1 (install libroscpp-dev ",
                            "librosbag-dev with scripts/install-deps.sh and rebuild)"));
#endif
  }
  return bag::OpenRos2Bag(path);  // A folder, .db3 or .mcap (refused with a reason).
}

// "x y z qx qy qz qw" (metres, Hamilton quaternion; TUM order).
Rigid3d ParsePose(const std::string& text, const char* flag) {
  std::istringstream in(text);
  double v[7];
  for (double& x : v) {
    if (!(in >> x)) throw UsageError(StrCat(flag, " takes 7 numbers \"x y z qx qy qz qw\""));
  }
  const Eigen::Quaterniond q(v[6], v[3], v[4], v[5]);
  if (!(q.norm() > 0.5 && q.norm() < 1.5)) throw UsageError(StrCat(flag, ": not a unit quaternion"));
  return Rigid3d(q.normalized(), Eigen::Vector3d(v[0], v[1], v[2]));
}

void PrintHuman(const std::string& out, const bag::ImportStats& s) {
  std::printf("%s: %d frames over %.2f s (%s)\n", out.c_str(), s.frames, s.duration_s,
              s.right ? "stereo" : "monocular");
  std::printf("images: %d left, %d right; unpaired %d left, %d right; %d out of order; "
              "largest pair offset %.3f ms\n",
              s.left_images, s.right_images, s.pairing.unpaired_left, s.pairing.unpaired_right,
              s.pairing.out_of_order, s.pairing.max_offset_ns * 1e-6);
  std::printf("cameras from %s\ncam0: %s\n", s.camera_source.c_str(), ToString(s.left.camera).c_str());
  if (s.right) {
    std::printf("cam1: %s\n      baseline %.4f m\n", ToString(s.right->camera).c_str(),
                (s.left.body_from_cam.Inverse() * s.right->body_from_cam).translation.norm());
  }
  std::printf("imu: %d samples; odometry: %d poses\n", s.imu_samples, s.odometry_poses);
}

std::string ToJson(const std::string& out, const bag::ImportStats& s) {
  JsonWriter json;
  json.BeginObject()
      .Field("out", out)
      .Field("frames", s.frames)
      .Field("stereo", s.right.has_value())
      .Field("duration_s", s.duration_s)
      .Field("left_images", s.left_images)
      .Field("right_images", s.right_images)
      .Field("unpaired_left", s.pairing.unpaired_left)
      .Field("unpaired_right", s.pairing.unpaired_right)
      .Field("out_of_order", s.pairing.out_of_order)
      .Field("max_pair_offset_ms", s.pairing.max_offset_ns * 1e-6)
      .Field("camera_source", s.camera_source)
      .Field("imu_samples", s.imu_samples)
      .Field("odometry_poses", s.odometry_poses);
  if (s.right) {
    json.Field("baseline_m",
               (s.left.body_from_cam.Inverse() * s.right->body_from_cam).translation.norm());
  }
  json.EndObject();
  return json.str();
}

}  // namespace

int RunDatasetImport(const Args& args) {
  std::string bag_path, out, left_yaml, right_yaml, base_from_cam;
  double tolerance_ms = 3.0;
  bool json = false;
  bag::ImportOptions options;
  ArgParser parser(
      "visloc dataset import",
      "Turns a ROS bag into an EuRoC-layout sequence for map build, localize and stream. ROS 1 "
      "bags (.bag) are read with Debian's rosbag library; ROS 2 bags (a folder with .db3 files, "
      "or one .db3) with CDR messages are read directly. Images: sensor_msgs/Image (mono8, "
      "mono16, rgb8, bgr8, rgba8, bgra8, bayer) or CompressedImage (JPEG, PNG). Cameras come "
      "from each image topic's sibling camera_info (plumb_bob, equidistant) or from sensor.yaml "
      "files. Left and right images are paired by header stamp; unpaired ones are reported.");
  parser.AddFlag("rosbag", &bag_path, "the bag: FILE.bag (ROS 1), or a ROS 2 bag folder / .db3", true);
  parser.AddFlag("left", &options.left_topic, "left (reference) camera's image topic", true);
  parser.AddFlag("right", &options.right_topic, "right camera's image topic (omit: monocular)");
  parser.AddFlag("left-info", &options.left_info_topic, "left camera_info topic (default: sibling)");
  parser.AddFlag("right-info", &options.right_info_topic, "right camera_info topic");
  parser.AddFlag("left-yaml", &left_yaml, "left camera's EuRoC sensor.yaml instead of camera_info");
  parser.AddFlag("right-yaml", &right_yaml, "right camera's EuRoC sensor.yaml");
  parser.AddFlag("imu", &options.imu_topic, "sensor_msgs/Imu topic (needs --left-yaml's T_BS)");
  parser.AddFlag("odometry", &options.odometry_topic, "nav_msgs/Odometry topic");
  parser.AddFlag("base-from-cam", &base_from_cam,
                 "camera pose on the odometry's child frame, \"x y z qx qy qz qw\" (default: "
                 "the odometry tracks the camera)");
  parser.AddFlag("pair-tolerance-ms", &tolerance_ms, "largest left/right stamp difference (3)");
  parser.AddFlag("out", &out, "the sequence folder to create", true);
  parser.AddSwitch("json", &json, "print one JSON object");
  if (!parser.Parse(args, std::cout)) return 0;
  if (!left_yaml.empty()) options.left_yaml = ReadSensorYaml(left_yaml);
  if (!right_yaml.empty()) options.right_yaml = ReadSensorYaml(right_yaml);
  if (!base_from_cam.empty()) options.base_from_cam = ParsePose(base_from_cam, "--base-from-cam");
  if (!(tolerance_ms >= 0 && tolerance_ms <= 1000)) {
    throw UsageError("--pair-tolerance-ms must be 0 to 1000");
  }
  options.pair_tolerance_ns = static_cast<int64_t>(tolerance_ms * 1e6);
  CheckFlags(options);
  std::unique_ptr<bag::BagReader> reader = OpenBag(bag_path);
  const bool progress = ShowProgress() && !json;
  const bag::ImportStats stats = bag::ImportBag(*reader, options, out, [&](int frames) {
    if (progress && frames % 20 == 0) std::fprintf(stderr, "\r\33[Kframe %d", frames);
  });
  if (progress) std::fprintf(stderr, "\r\33[K");
  if (json) {
    std::cout << ToJson(out, stats) << "\n";
  } else {
    PrintHuman(out, stats);
  }
  return 0;
}

}  // namespace visloc::cli
