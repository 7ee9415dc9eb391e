#pragma once
// A recording's messages, whichever bag format holds them. Implementations: ROS 2 bags
// (ros2_bag.h, always built) and ROS 1 bags (ros/rosbag1/, built when Debian's rosbag library
// is installed).

#include <functional>
#include <string>
#include <vector>

#include "ros/messages/ros_messages.h"

namespace visloc::bag {

class BagReader {
 public:
  virtual ~BagReader() = default;
  // Every topic with its type and message count.
  virtual std::vector<ros_msg::TopicInfo> Topics() = 0;
  // Calls `visit` for each message of `topics`, decoded, in recording order. A message that
  // cannot be decoded throws InputError naming the topic and its time.
  virtual void Read(const std::vector<std::string>& topics,
                    const std::function<void(const ros_msg::BagMessage&)>& visit) = 0;
};

}  // namespace visloc::bag
