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

RosHeader HeaderOf(const std_msgs::Header& header) {
  return {static_cast<int64_t>(header.stamp.toNSec()), header.frame_id};
}

std::string_view BytesOf(const std::vector<uint8_t>& data) {
  return std::string_view(reinterpret_cast<const char*>(data.data()), data.size());
}

Message Decode(const rosbag::MessageInstance& m, const std::string& type) {
  if (type == "sensor_msgs/Image") {
    const auto msg = m.instantiate<sensor_msgs::Image>();
    return ImageMessage{HeaderOf(msg->header),
                        DecodeRawImage(msg->width, msg->height, msg->encoding,
                                       msg->is_bigendian != 0, msg->step, BytesOf(msg->data))};
  }
  if (type == "sensor_msgs/CompressedImage") {
    const auto msg = m.instantiate<sensor_msgs::CompressedImage>();
    return ImageMessage{HeaderOf(msg->header), DecodeCompressedImage(msg->format, BytesOf(msg->data))};
  }
  if (type == "sensor_msgs/CameraInfo") {
    const auto msg = m.instantiate<sensor_msgs::CameraInfo>();
    CameraInfoMessage info;
    info.header = HeaderOf(msg->header);
    info.width = ImageSide(msg->width);
    info.height = ImageSide(msg->height);
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
    return ImuMessage{HeaderOf(msg->header), Eigen::Vector3d(w.x, w.y, w.z),
                      Eigen::Vector3d(a.x, a.y, a.z)};
  }
  if (type == "nav_msgs/Odometry") {
    const auto msg = m.instantiate<nav_msgs::Odometry>();
    const auto& p = msg->pose.pose.position;
    const auto& q = msg->pose.pose.orientation;
    return OdometryMessage{HeaderOf(msg->header), msg->child_frame_id,
                           OdometryPose(Eigen::Quaterniond(q.w, q.x, q.y, q.z),
                                        Eigen::Vector3d(p.x, p.y, p.z))};
  }
  return UnknownMessage{};
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

  std::vector<TopicInfo> Topics() override {
    std::map<std::string, TopicInfo> topics;
    rosbag::View view(bag_);
    for (const rosbag::ConnectionInfo* c : view.getConnections()) {
      TopicInfo& info = topics[c->topic];
      info.name = c->topic;
      info.type = c->datatype;
    }
    for (auto& [name, info] : topics) {
      info.messages = rosbag::View(bag_, rosbag::TopicQuery(name)).size();
    }
    std::vector<TopicInfo> list;
    for (const auto& [name, info] : topics) list.push_back(info);
    return list;
  }

  void Read(const std::vector<std::string>& topics,
            const std::function<void(const BagMessage&)>& visit) override {
    try {
      rosbag::View view(bag_, rosbag::TopicQuery(topics));
      for (const rosbag::MessageInstance& m : view) {
        BagMessage message{m.getTopic(), static_cast<int64_t>(m.getTime().toNSec()),
                           UnknownMessage{}};
        try {
          message.message = Decode(m, NormalizeTypeName(m.getDataType()));
        } catch (const ros::Exception& e) {  // Includes rosbag's and serialization errors.
          throw InputError(StrCat(message.topic, " message recorded at ",
                                  StampText(message.record_time_ns), " s: ", e.what()));
        } catch (const InputError& e) {
          throw InputError(StrCat(message.topic, " message recorded at ",
                                  StampText(message.record_time_ns), " s: ", e.what()));
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
