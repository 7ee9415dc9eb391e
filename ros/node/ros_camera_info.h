#pragma once
// sensor_msgs/CameraInfo (ROS 1) as ros_messages' plain struct, for both of the node's modes.

#include <algorithm>

#include <sensor_msgs/CameraInfo.h>

#include "ros/messages/ros_messages.h"

namespace visloc::ros_node {

inline ros_msg::CameraInfoMessage CameraInfoFromRos(const sensor_msgs::CameraInfo& msg) {
  ros_msg::CameraInfoMessage info;
  info.width = ros_msg::ImageSide(msg.width);
  info.height = ros_msg::ImageSide(msg.height);
  info.distortion_model = msg.distortion_model;
  info.d = msg.D;
  std::copy(msg.K.begin(), msg.K.end(), info.k.begin());
  std::copy(msg.R.begin(), msg.R.end(), info.r.begin());
  std::copy(msg.P.begin(), msg.P.end(), info.p.begin());
  return info;
}

}  // namespace visloc::ros_node
