#include "ros/bag/ros2_messages.h"

#include <Eigen/Geometry>

#include "core/util/check.h"
#include "ros/bag/cdr.h"

namespace visloc::bag {
namespace {

ros_msg::RosHeader ReadHeader(CdrReader& in) {
  ros_msg::RosHeader header;
  const int32_t sec = in.I32("header.stamp.sec");
  const uint32_t nanosec = in.U32("header.stamp.nanosec");
  if (nanosec >= 1000000000u) {
    throw InputError(StrCat("CDR: header.stamp.nanosec is ", nanosec, " (at most 999999999)"));
  }
  header.stamp_ns = static_cast<int64_t>(sec) * 1000000000 + nanosec;
  header.frame_id = in.String("header.frame_id");
  return header;
}

template <size_t N>
void ReadArray(CdrReader& in, std::array<double, N>& out, const char* what) {
  for (double& v : out) v = in.F64(what);
}

Eigen::Vector3d ReadVector3(CdrReader& in, const char* what) {
  Eigen::Vector3d v;
  for (int i = 0; i < 3; ++i) v[i] = in.F64(what);
  return v;
}

void SkipCovariance(CdrReader& in, int size, const char* what) {
  for (int i = 0; i < size; ++i) in.F64(what);
}

ros_msg::ImageMessage ReadImage(CdrReader& in) {
  ros_msg::ImageMessage msg;
  msg.header = ReadHeader(in);
  const uint32_t height = in.U32("height");
  const uint32_t width = in.U32("width");
  const std::string encoding = in.String("encoding");
  const bool big_endian = in.U8("is_bigendian") != 0;
  const uint32_t step = in.U32("step");
  const std::string_view data = in.Bytes("data");
  msg.grey = ros_msg::DecodeRawImage(width, height, encoding, big_endian, step, data);
  return msg;
}

ros_msg::ImageMessage ReadCompressedImage(CdrReader& in) {
  ros_msg::ImageMessage msg;
  msg.header = ReadHeader(in);
  const std::string format = in.String("format");
  msg.grey = ros_msg::DecodeCompressedImage(format, in.Bytes("data"));
  return msg;
}

ros_msg::CameraInfoMessage ReadCameraInfo(CdrReader& in) {
  ros_msg::CameraInfoMessage msg;
  msg.header = ReadHeader(in);
  msg.height = ros_msg::ImageSide(in.U32("height"));
  msg.width = ros_msg::ImageSide(in.U32("width"));
  msg.distortion_model = in.String("distortion_model");
  msg.d = in.F64Sequence("d");
  ReadArray(in, msg.k, "k");
  ReadArray(in, msg.r, "r");
  ReadArray(in, msg.p, "p");
  // binning_x, binning_y and the region of interest follow; the importer uses full frames.
  return msg;
}

ros_msg::ImuMessage ReadImu(CdrReader& in) {
  ros_msg::ImuMessage msg;
  msg.header = ReadHeader(in);
  for (int i = 0; i < 4; ++i) in.F64("orientation");
  SkipCovariance(in, 9, "orientation_covariance");
  msg.gyro_radps = ReadVector3(in, "angular_velocity");
  SkipCovariance(in, 9, "angular_velocity_covariance");
  msg.accel_mps2 = ReadVector3(in, "linear_acceleration");
  return msg;
}

ros_msg::OdometryMessage ReadOdometry(CdrReader& in) {
  ros_msg::OdometryMessage msg;
  msg.header = ReadHeader(in);
  msg.child_frame_id = in.String("child_frame_id");
  const Eigen::Vector3d position = ReadVector3(in, "pose.pose.position");
  double q[4];  // x y z w
  for (double& c : q) c = in.F64("pose.pose.orientation");
  msg.odom_from_child = ros_msg::OdometryPose(Eigen::Quaterniond(q[3], q[0], q[1], q[2]), position);
  return msg;
}

}  // namespace

ros_msg::Message DecodeRos2Message(const std::string& type, std::string_view cdr) {
  CdrReader in(cdr);
  if (type == "sensor_msgs/Image") return ReadImage(in);
  if (type == "sensor_msgs/CompressedImage") return ReadCompressedImage(in);
  if (type == "sensor_msgs/CameraInfo") return ReadCameraInfo(in);
  if (type == "sensor_msgs/Imu") return ReadImu(in);
  if (type == "nav_msgs/Odometry") return ReadOdometry(in);
  return ros_msg::UnknownMessage{};
}

}  // namespace visloc::bag
