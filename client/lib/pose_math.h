#pragma once
// The little rigid-body algebra the client library needs on wire poses (v1::Pose: translation
// in metres, Hamilton quaternion), without Eigen or the engine.

#include "visloc/v1/visloc.pb.h"

namespace visloc::client {

// a_from_c = a_from_b * b_from_c.
v1::Pose Compose(const v1::Pose& a_from_b, const v1::Pose& b_from_c);
// b_from_a from a_from_b.
v1::Pose Invert(const v1::Pose& a_from_b);

// The pose now, from the pose at an earlier frame and the odometry of both frames:
// map_from_cam_now = map_from_cam_then * inverse(odom_from_cam_then) * odom_from_cam_now. Only
// the odometry's motion between the frames is used, never its origin.
v1::Pose PropagateByOdometry(const v1::Pose& map_from_cam_then, const v1::Pose& odom_from_cam_then,
                             const v1::Pose& odom_from_cam_now);

}  // namespace visloc::client
