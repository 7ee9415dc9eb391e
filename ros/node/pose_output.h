#pragma once
// What visloc_ros_node publishes for an answer, as plain functions (no ROS types) so that the
// rules are unit-tested without a ROS master:
// - a pose only for an answer that has one and is tracking, limited or relocalized; never
//   while lost, initializing or on error, so a consumer never steers on a stale pose;
// - the covariance in the map frame, as geometry_msgs/PoseWithCovariance defines it;
// - REP 105's map -> odom: map_from_odom = map_from_cam * (odom_from_cam)^-1, with the
//   odometry's camera pose at the frame's stamp.

#include <array>
#include <cstdint>
#include <deque>
#include <optional>
#include <vector>

#include "core/geometry/rigid3.h"
#include "core/geometry/trajectory.h"
#include "proto/geometry_convert.h"
#include "visloc/v1/visloc.pb.h"

namespace visloc::ros_node {

bool IsPublishable(const v1::LocalizeResponse& response);

// The pose the node publishes in its map frame. REP 105 wants `map` with z up: the answer's
// pose in the map's site frame (site_from_cam: the frame map align tied it to, else its level
// frame) when `site_frame` asks for it and the server gives it; else the map frame's (the first
// camera's, a map that records no up, or servers before it). `in_site` says which.
template <typename Answer>
Rigid3d PublishedPose(const Answer& answer, bool site_frame, bool* in_site = nullptr) {
  const bool site = site_frame && answer.has_site_from_cam();
  if (in_site) *in_site = site;
  return proto::FromProto(site ? answer.site_from_cam() : answer.map_from_cam(),
                          site ? "site_from_cam" : "map_from_cam");
}

// visloc's covariance is over a right perturbation of map_from_cam (camera frame; translation
// in m, then rotation in rad); ROS's is over the pose in its parent (map) frame with fixed-axis
// rotations. Both blocks are rotated into the map frame. Row-major 6x6; zeros when the answer
// has no covariance.
std::array<double, 36> CovarianceInMapFrame(const Rigid3d& map_from_cam,
                                            const std::vector<double>& covariance_cam);

Rigid3d MapFromOdom(const Rigid3d& map_from_cam, const Rigid3d& odom_from_cam);

// The odometry's recent poses, to look up the robot's odometry pose at an image's stamp.
class OdometryBuffer {
 public:
  explicit OdometryBuffer(int64_t keep_ns = 5'000'000'000) : keep_ns_(keep_ns) {}
  void Add(int64_t stamp_ns, const Rigid3d& odom_from_child);
  // Interpolated between the neighbouring samples; nothing past the newest sample unless
  // `max_extrapolation_ns` allows holding it that long. The node never does: an earlier sample
  // standing in for the image's own leaves a frame's motion out of the prior (sensor_sync.h).
  std::optional<Rigid3d> At(int64_t stamp_ns, int64_t max_extrapolation_ns = 0) const;

 private:
  int64_t keep_ns_;
  Trajectory samples_;
};

}  // namespace visloc::ros_node
