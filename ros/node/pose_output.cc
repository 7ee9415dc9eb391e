#include "ros/node/pose_output.h"

#include <Eigen/Core>

namespace visloc::ros_node {

bool IsPublishable(const v1::LocalizeResponse& response) {
  if (!response.has_pose()) return false;
  switch (response.status()) {
    case v1::STATUS_TRACKING:
    case v1::STATUS_LIMITED:
    case v1::STATUS_RELOCALIZED:
      return true;
    default:
      return false;
  }
}

std::array<double, 36> CovarianceInMapFrame(const Rigid3d& map_from_cam,
                                            const std::vector<double>& covariance_cam) {
  std::array<double, 36> out{};
  if (covariance_cam.size() != 36) return out;
  using Matrix6d = Eigen::Matrix<double, 6, 6, Eigen::RowMajor>;
  const Matrix6d cam = Eigen::Map<const Matrix6d>(covariance_cam.data());
  Matrix6d rotate = Matrix6d::Zero();
  rotate.topLeftCorner<3, 3>() = map_from_cam.rotation.toRotationMatrix();
  rotate.bottomRightCorner<3, 3>() = map_from_cam.rotation.toRotationMatrix();
  Eigen::Map<Matrix6d>(out.data()) = rotate * cam * rotate.transpose();
  return out;
}

Rigid3d MapFromOdom(const Rigid3d& map_from_cam, const Rigid3d& odom_from_cam) {
  return map_from_cam * odom_from_cam.Inverse();
}

void OdometryBuffer::Add(int64_t stamp_ns, const Rigid3d& odom_from_child) {
  if (!samples_.empty() && stamp_ns <= samples_.back().timestamp_ns) return;  // Out of order.
  samples_.push_back({stamp_ns, odom_from_child});
  while (samples_.size() > 2 && samples_.front().timestamp_ns < stamp_ns - keep_ns_) {
    samples_.erase(samples_.begin());
  }
}

std::optional<Rigid3d> OdometryBuffer::At(int64_t stamp_ns, int64_t max_extrapolation_ns) const {
  if (samples_.empty()) return std::nullopt;
  const StampedPose& newest = samples_.back();
  if (stamp_ns >= newest.timestamp_ns) {
    if (stamp_ns - newest.timestamp_ns <= max_extrapolation_ns) return newest.pose;
    return std::nullopt;
  }
  return InterpolateAt(samples_, stamp_ns, keep_ns_);
}

}  // namespace visloc::ros_node
