// Fuzz target: ROS 2 bag messages (CDR, ros/bag/cdr.h), as `visloc dataset import` reads them
// from a bag a user hands it. The first byte picks the message type; the rest is the message.
// A CameraInfo that decodes is also turned into a camera and a stereo rig, as the importer
// does. Bad messages must end in InputError naming the field, never a crash or a huge
// allocation.

#include <cstdint>
#include <string>

#include "core/util/check.h"
#include "fuzz/fuzz_input.h"
#include "ros/messages/ros_messages.h"
#include "ros/bag/ros2_messages.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const char* const kTypes[] = {"sensor_msgs/Image", "sensor_msgs/CompressedImage",
                                       "sensor_msgs/CameraInfo", "sensor_msgs/Imu",
                                       "nav_msgs/Odometry"};
  visloc::fuzz::FuzzInput input(data, size);
  const std::string type = kTypes[input.Byte() % 5];
  const std::string message = input.Rest();
  try {
    const visloc::ros_msg::Message decoded = visloc::bag::DecodeRos2Message(type, message);
    if (const auto* info = std::get_if<visloc::ros_msg::CameraInfoMessage>(&decoded)) {
      visloc::ros_msg::CameraFromInfo(*info, "/fuzz/camera_info");
      visloc::ros_msg::LeftFromRight(*info, *info);
    }
  } catch (const visloc::InputError&) {
    // Refused with a message.
  } catch (const visloc::CheckError&) {
    // A camera the model refuses (Camera's own checks): also a clear error.
  }
  return 0;
}
