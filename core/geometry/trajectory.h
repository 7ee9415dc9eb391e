#pragma once
// Time-stamped poses. What a pose means (which frames) is named by the variable holding the
// trajectory, e.g. `map_from_cam` or `world_from_body`.

#include <cstdint>
#include <optional>
#include <vector>

#include "core/geometry/rigid3.h"

namespace visloc {

struct StampedPose {
  int64_t timestamp_ns = 0;
  Rigid3d pose;
};

using Trajectory = std::vector<StampedPose>;

inline double NsToSeconds(int64_t ns) { return static_cast<double>(ns) * 1e-9; }
inline int64_t SecondsToNs(double seconds) {
  return static_cast<int64_t>(seconds * 1e9 + (seconds >= 0 ? 0.5 : -0.5));
}

// The pose at `timestamp_ns`, interpolated between the two neighbouring samples of a
// trajectory sorted by time. std::nullopt outside the trajectory's time span or when the
// neighbours are more than `max_gap_ns` apart (no pose is invented across a gap).
std::optional<Rigid3d> InterpolateAt(const Trajectory& trajectory, int64_t timestamp_ns,
                                     int64_t max_gap_ns);

// Expresses every pose relative to `reference_from_frame`: result = reference^-1 * pose.
// With the first pose as the reference this gives a trajectory starting at the identity.
Trajectory RelativeTo(const Trajectory& frame_poses, const Rigid3d& reference);

}  // namespace visloc
