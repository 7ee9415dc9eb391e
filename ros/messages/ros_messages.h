#pragma once
// The ROS messages a recording is imported from, independent of where they came from: a ROS 1
// bag (read with Debian's rosbag library, ros/rosbag1/) or a ROS 2 bag (SQLite + CDR, read by
// ros/bag/ros2_bag.h). Readers fill these; the importer (bag_import.h) never sees ROS types.
//
// Times are the messages' header stamps in nanoseconds. Frames are ROS frame ids (strings);
// poses follow the `a_from_b` naming of core/geometry/rigid3.h.

#include <algorithm>
#include <array>
#include <cstdint>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "core/camera/camera.h"
#include "core/geometry/rigid3.h"

namespace visloc::ros_msg {

struct RosHeader {
  int64_t stamp_ns = 0;
  std::string frame_id;
};

// sensor_msgs/Image, decoded to 8-bit grey; or sensor_msgs/CompressedImage, decoded the same.
struct ImageMessage {
  RosHeader header;
  cv::Mat grey;  // CV_8UC1
};

// sensor_msgs/CameraInfo (ROS 1 names D K R P; ROS 2 names d k r p). Row-major matrices.
struct CameraInfoMessage {
  RosHeader header;
  int width = 0;
  int height = 0;
  std::string distortion_model;  // "plumb_bob", "rational_polynomial", "equidistant", ...
  std::vector<double> d;
  std::array<double, 9> k{};
  std::array<double, 9> r{};   // rect_from_cam: the stereo rectification rotation.
  std::array<double, 12> p{};  // Projection in the rectified frame; p[3] = -fx' * baseline.
};

// sensor_msgs/Imu: rates and specific force in header.frame_id.
struct ImuMessage {
  RosHeader header;
  Eigen::Vector3d gyro_radps = Eigen::Vector3d::Zero();
  Eigen::Vector3d accel_mps2 = Eigen::Vector3d::Zero();
};

// nav_msgs/Odometry: the pose of child_frame_id in header.frame_id (the odometry frame).
struct OdometryMessage {
  RosHeader header;
  std::string child_frame_id;
  Rigid3d odom_from_child;
};

struct UnknownMessage {};

using Message =
    std::variant<UnknownMessage, ImageMessage, CameraInfoMessage, ImuMessage, OdometryMessage>;

// One message read from a bag: its topic, the time it was recorded and its decoded content.
struct BagMessage {
  std::string topic;
  int64_t record_time_ns = 0;
  Message message;
};

struct TopicInfo {
  std::string name;
  std::string type;  // "sensor_msgs/Image" (ROS 1) or "sensor_msgs/msg/Image" (ROS 2).
  int64_t messages = 0;
};

// "12.345678901": a stamp in seconds, for messages.
std::string StampText(int64_t stamp_ns);

// The message kinds the importer understands, named the ROS 1 way ("sensor_msgs/Image"); a
// ROS 2 name ("sensor_msgs/msg/Image") is normalized to it. Empty for other types.
std::string NormalizeTypeName(const std::string& type);

// Decodes a raw sensor_msgs/Image buffer to 8-bit grey. Encodings: mono8, 8UC1, mono16 and
// 16UC1 (scaled to 8 bits), rgb8, bgr8, rgba8, bgra8 and the 8-bit Bayer patterns. Throws
// InputError naming the problem (unknown encoding, a step smaller than a row, too few bytes).
cv::Mat DecodeRawImage(int64_t width, int64_t height, const std::string& encoding,
                       bool is_bigendian, int64_t step, std::string_view data);
// Decodes a sensor_msgs/CompressedImage (JPEG or PNG) to 8-bit grey; throws InputError.
cv::Mat DecodeCompressedImage(const std::string& format, std::string_view data);

// An image side from a message's uint32 field, as an int: values beyond 2^30 (no camera has them)
// become 2^30, which every size check refuses.
inline int ImageSide(uint32_t side) { return static_cast<int>(std::min<uint32_t>(side, 1u << 30)); }

// nav_msgs/Odometry's pose as odom_from_child. Throws InputError for a zero quaternion (an
// unset orientation); others are normalized.
Rigid3d OdometryPose(const Eigen::Quaterniond& orientation, const Eigen::Vector3d& position);

// A ROS camera's model in visloc's terms. `plumb_bob` and `rational_polynomial` become
// radial-tangential (k3 and higher must be negligible: under `max_dropped_term_px` at the image
// corner, else InputError), `equidistant` becomes Kannala-Brandt. Throws InputError naming the
// problem (zero focal length, unknown model, no image size).
Camera CameraFromInfo(const CameraInfoMessage& info, const std::string& topic,
                      double max_dropped_term_px = 0.5);

// The right camera's pose relative to the left one from a stereo pair's CameraInfo, the way
// ROS's stereo calibration writes it: both share a rectified frame, R = rect_from_cam, and the
// right camera's P[3] = -fx' * baseline. Returns left_from_right. Throws InputError when the
// right P carries no baseline (not a calibrated stereo pair).
Rigid3d LeftFromRight(const CameraInfoMessage& left, const CameraInfoMessage& right);

}  // namespace visloc::ros_msg
