#pragma once
// Decoding of the ROS 2 messages the importer reads, from their CDR bytes (cdr.h), following
// the message definitions of ROS 2's common_interfaces (std_msgs/Header: builtin_interfaces/
// Time stamp {int32 sec, uint32 nanosec}, string frame_id).

#include <string>
#include <string_view>

#include "ros/messages/ros_messages.h"

namespace visloc::bag {

// `type` as NormalizeTypeName returns it. Raw and compressed images are decoded to grey.
// Throws InputError naming the type and the field for a malformed message; UnknownMessage for
// types the importer does not read.
ros_msg::Message DecodeRos2Message(const std::string& type, std::string_view cdr);

}  // namespace visloc::bag
