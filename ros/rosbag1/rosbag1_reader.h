#pragma once
// ROS 1 bags (format 2.0, plain, bz2 or lz4 chunks), read with Debian's rosbag_storage library
// and the sensor_msgs / nav_msgs message classes, so the bag format is ROS's own code's job.

#include <memory>
#include <string>

#include "ros/bag/bag_reader.h"

namespace visloc::bag {

// Throws InputError naming the file when rosbag cannot open it.
std::unique_ptr<BagReader> OpenRos1Bag(const std::string& path);

}  // namespace visloc::bag
