#pragma once
// visloc_ros_node's mapping mode (~mode:=map): a ROS 1 stereo camera streamed to visloc-server,
// which builds a map as the frames arrive (the Mapping service, through the client library's
// MappingSession: bounded frames in flight, the job resumed across link cuts).
//
// Subscribes (remap them):   left/image, left/camera_info, right/image, right/camera_info
//                            (sensor_msgs/Image; the pair's CameraInfo as ROS's stereo
//                            calibration writes it: R, and the right P carrying the baseline)
// Publishes:                 ~status (std_msgs/String: the job's state, frames, keyframes,
//                            points), ~mapping_pose (geometry_msgs/PoseStamped, ~map_frame: the
//                            left camera as the mapper has it so far)
// Service:                   ~finish_map (std_srvs/Trigger): ends the run; the server adjusts
//                            the whole map and publishes it under ~map. The answer says what
//                            was published, or why nothing was.
// Left and right images are paired by exact stamp; an image without its partner within 2 s is
// dropped (counted in the status).

#include <ros/ros.h>

namespace visloc::ros_node {

// Runs the mapping node until ROS shuts down; returns the process's exit code.
int RunMappingNode(ros::NodeHandle& nh, ros::NodeHandle& pnh);

}  // namespace visloc::ros_node
