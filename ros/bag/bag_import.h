#pragma once
// `visloc dataset import`: a bag becomes a sequence in the EuRoC layout (dataset/euroc.h) that
// `map build`, `localize` and `stream` read.
//
// Cameras come from the bag's sensor_msgs/CameraInfo (the first message of each camera's info
// topic) or from EuRoC sensor.yaml files. With CameraInfo, the left camera is the body frame
// (T_BS = identity) and the right camera's pose comes from the stereo calibration's R and P.
// Left and right images are paired by header stamp within a tolerance (stereo_pairer.h). The
// sequence is written to OUT.partial and renamed to OUT only when complete, so an import that
// fails leaves no half-written dataset behind.

#include <cstdint>
#include <functional>
#include <optional>
#include <string>

#include "dataset/dataset.h"
#include "ros/bag/bag_reader.h"
#include "ros/bag/stereo_pairer.h"

namespace visloc::bag {

struct ImportOptions {
  std::string left_topic;        // sensor_msgs/Image or CompressedImage. Required.
  std::string right_topic;       // Empty: a monocular sequence (localization only).
  std::string left_info_topic;   // Empty: the image topic's sibling "camera_info".
  std::string right_info_topic;
  std::string imu_topic;         // sensor_msgs/Imu; optional.
  std::string odometry_topic;    // nav_msgs/Odometry; optional.
  // Cameras from sensor.yaml files instead of CameraInfo (both when stereo).
  std::optional<CameraInfo> left_yaml;
  std::optional<CameraInfo> right_yaml;
  // The camera's pose on the odometry's child frame (base_link): the odometry's poses become
  // camera poses as odom_from_base * base_from_cam. Identity when the odometry tracks the
  // camera itself.
  Rigid3d base_from_cam;
  int64_t pair_tolerance_ns = 3'000'000;  // 3 ms: hardware-synchronized pairs share a stamp.
  double max_dropped_distortion_px = 0.5;  // For k3.. of plumb_bob (ros_msg::CameraFromInfo).

  // Throws CheckError naming the first bad value.
  void Check() const;
};

struct ImportStats {
  int left_images = 0;
  int right_images = 0;
  int frames = 0;  // Written: stereo pairs, or left images of a monocular sequence.
  PairingStats pairing;
  int imu_samples = 0;
  int odometry_poses = 0;
  std::string camera_source;  // "camera_info" or "sensor.yaml"
  CameraInfo left;
  std::optional<CameraInfo> right;
  double duration_s = 0.0;
};

// Progress: frames written so far.
using ImportProgressFn = std::function<void(int)>;

// Throws InputError naming the problem: a topic missing from the bag (the error lists the
// bag's topics of the right type), a topic of the wrong type, an image whose size differs from
// its camera, a camera_info that visloc cannot model, no frame at all; CheckError for bad
// options; an existing non-empty `out_dir` is refused.
ImportStats ImportBag(BagReader& reader, const ImportOptions& options,
                      const std::string& out_dir, const ImportProgressFn& progress = nullptr);

// The camera_info topic image_transport pairs with an image topic: "/cam0/image_raw" and
// "/cam0/image_raw/compressed" -> "/cam0/camera_info".
std::string CameraInfoTopicFor(const std::string& image_topic);

}  // namespace visloc::bag
