#pragma once
// ROS 2 bags in the sqlite3 storage format: a folder with metadata.yaml and one or more .db3
// files (split bags are read in name order), or a single .db3 file. Messages must be CDR
// (ROS 2's default serialization). MCAP bags are refused with a clear message: Debian 12 has no
// MCAP library, and `ros2 bag convert` turns them into sqlite3 bags.

#include <memory>
#include <string>

#include "ros/bag/bag_reader.h"

namespace visloc::bag {

// Throws InputError naming the path when it is not a ROS 2 sqlite3 bag.
std::unique_ptr<BagReader> OpenRos2Bag(const std::string& path);

}  // namespace visloc::bag
