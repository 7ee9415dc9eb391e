#include "core/geometry/trajectory.h"

#include <algorithm>

namespace visloc {

std::optional<Rigid3d> InterpolateAt(const Trajectory& trajectory, int64_t timestamp_ns,
                                     int64_t max_gap_ns) {
  if (trajectory.empty()) return std::nullopt;
  const auto after = std::lower_bound(
      trajectory.begin(), trajectory.end(), timestamp_ns,
      [](const StampedPose& sample, int64_t t) { return sample.timestamp_ns < t; });
  if (after == trajectory.end()) return std::nullopt;
  if (after->timestamp_ns == timestamp_ns) return after->pose;
  if (after == trajectory.begin()) return std::nullopt;
  const auto before = std::prev(after);
  const int64_t gap = after->timestamp_ns - before->timestamp_ns;
  if (gap > max_gap_ns) return std::nullopt;
  const double t = static_cast<double>(timestamp_ns - before->timestamp_ns) / gap;
  return Interpolate(before->pose, after->pose, t);
}

Trajectory RelativeTo(const Trajectory& frame_poses, const Rigid3d& reference) {
  const Rigid3d reference_inverse = reference.Inverse();
  Trajectory result;
  result.reserve(frame_poses.size());
  for (const StampedPose& sample : frame_poses) {
    result.push_back({sample.timestamp_ns, reference_inverse * sample.pose});
  }
  return result;
}

}  // namespace visloc
