#include "ros/rosbag1/rosbag1_reader.h"

#include <filesystem>
#include <map>

#include <nav_msgs/Odometry.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/CompressedImage.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>

#include <Eigen/Geometry>

#include "core/util/check.h"

namespace visloc::bag {
namespace {

ros_msg::RosHeader HeaderOf(const std_msgs::Header& header) {
  return {static_cast<int64_t>(header.stamp.toNSec()), header.frame_id};
}

std::string_view BytesOf(const std::vector<uint8_t>& data) {
  return std::string_view(reinterpret_cast<const char*>(data.data()), data.size());
}

ros_msg::Message Decode(const rosbag::MessageInstance& m, const std::string& type) {
  if (type == "sensor_msgs/Image") {
    const auto msg = m.instantiate<sensor_msgs::Image>();
    return ros_msg::ImageMessage{HeaderOf(msg->header),
                        ros_msg::DecodeRawImage(msg->width, msg->height, msg->encoding,
                                       msg->is_bigendian != 0, msg->step, BytesOf(msg->data))};
  }
  if (type == "sensor_msgs/CompressedImage") {
    const auto msg = m.instantiate<sensor_msgs::CompressedImage>();
    return ros_msg::ImageMessage{HeaderOf(msg->header), ros_msg::DecodeCompressedImage(msg->format, BytesOf(msg->data))};
  }
  if (type == "sensor_msgs/CameraInfo") {
    const auto msg = m.instantiate<sensor_msgs::CameraInfo>();
    ros_msg::CameraInfoMessage info;
    info.header = HeaderOf(msg->header);
    info.width = ros_msg::ImageSide(msg->width);
    info.height = ros_msg::ImageSide(msg->height);
    info.distortion_model = msg->distortion_model;
    info.d = msg->D;
    std::copy(msg->K.begin(), msg->K.end(), info.k.begin());
    std::copy(msg->R.begin(), msg->R.end(), info.r.begin());
    std::copy(msg->P.begin(), msg->P.end(), info.p.begin());
    return info;
  }
  if (type == "sensor_msgs/Imu") {
    const auto msg = m.instantiate<sensor_msgs::Imu>();
    const auto& w = msg->angular_velocity;
    const auto& a = msg->linear_acceleration;
    return ros_msg::ImuMessage{HeaderOf(msg->header), Eigen::Vector3d(w.x, w.y, w.z),
                      Eigen::Vector3d(a.x, a.y, a.z)};
  }
  if (type == "nav_msgs/Odometry") {
    const auto msg = m.instantiate<nav_msgs::Odometry>();
    const auto& p = msg->pose.pose.position;
    const auto& q = msg->pose.pose.orientation;
    return ros_msg::OdometryMessage{HeaderOf(msg->header), msg->child_frame_id,
                           ros_msg::OdometryPose(Eigen::Quaterniond(q.w, q.x, q.y, q.z),
                                        Eigen::Vector3d(p.x, p.y, p.z))};
  }
  return ros_msg::UnknownMessage{};
}

class Ros1Bag : public BagReader {
 public:
  explicit Ros1Bag(const std::string& path) : path_(path) {
    std::error_code error;
    if (!std::filesystem::exists(path, error)) throw NotFoundError(StrCat(path, ": no such bag"));
    try {
      bag_.open(path, rosbag::bagmode::Read);
    } catch (const rosbag::BagException& e) {
      throw InputError(StrCat(path, ": not a readable ROS 1 bag: ", e.what()));
    }
  }

  std::vector<ros_msg::TopicInfo> Topics() override {
    std::map<std::string, ros_msg::TopicInfo> topics;
    rosbag::View view(bag_);
    for (const rosbag::ConnectionInfo* c : view.getConnections()) {
      ros_msg::TopicInfo& info = topics[c->topic];
      info.name = c->topic;
      info.type = c->datatype;
    }
    for (auto& [name, info] : topics) {
      info.messages = rosbag::View(bag_, rosbag::TopicQuery(name)).size();
    }
    std::vector<ros_msg::TopicInfo> list;
    for (const auto& [name, info] : topics) list.push_back(info);
    return list;
  }

  void Read(const std::vector<std::string>& topics,
            const std::function<void(const ros_msg::BagMessage&)>& visit) override {
    try {
      rosbag::View view(bag_, rosbag::TopicQuery(topics));
      for (const rosbag::MessageInstance& m : view) {
        ros_msg::BagMessage message{m.getTopic(), static_cast<int64_t>(m.getTime().toNSec()),
                           ros_msg::UnknownMessage{}};
        try {
          message.message = Decode(m, ros_msg::NormalizeTypeName(m.getDataType()));
        } catch (const ros::Exception& e) {  // Includes rosbag's and serialization errors.
          throw InputError(StrCat(message.topic, " message recorded at ",
                                  ros_msg::StampText(message.record_time_ns), " s: ", e.what()));
        } catch (const InputError& e) {
          throw InputError(StrCat(message.topic, " message recorded at ",
                                  ros_msg::StampText(message.record_time_ns), " s: ", e.what()));
        }
        visit(message);
      }
    } catch (const rosbag::BagException& e) {
      throw InputError(StrCat(path_, ": ", e.what()));
    }
  }

 private:
  std::string path_;
  rosbag::Bag bag_;
};

}  // namespace

std::unique_ptr<BagReader> OpenRos1Bag(const std::string& path) {
  return std::make_unique<Ros1Bag>(path);
}

}  // namespace visloc::bag
