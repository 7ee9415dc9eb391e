#pragma once
// What the server is doing now, as plain values with no transport types: the live sessions, the
// maps and their cache, the worker permits. One snapshot serves every reader (the log, tests,
// and the operator's page and metrics to come), so they never disagree.

#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/geometry/rigid3.h"
#include "core/localization/localizer.h"

namespace visloc::server {

// One Localize stream: a robot on a map.
struct SessionStatus {
  uint64_t id = 0;
  std::string map;
  std::string robot_id;
  std::chrono::system_clock::time_point started;
  uint64_t frames = 0;     // Arrived, answered or skipped.
  uint64_t localized = 0;  // With a visual pose (not from motion alone).
  uint64_t skipped = 0;
  uint64_t errors = 0;
  // The last answered frame.
  TrackingStatus status = TrackingStatus::kInitializing;
  bool has_pose = false;
  Rigid3d map_from_cam;
  double position_sigma_m = 0.0;  // Per axis.
  int inliers = 0;
  double inlier_ratio = 0.0;
  double server_ms = 0.0;
  double frame_rate_hz = 0.0;  // Arrivals per second over the last few seconds.
  std::chrono::system_clock::time_point last_frame;  // Epoch before the first frame.
  // Since when the robot has had no pose (from the start until its first); none while it has.
  std::optional<std::chrono::system_clock::time_point> without_pose_since;
};

// A map the server holds loaded.
struct LoadedMapStatus {
  std::string name;
  int users = 0;  // Sessions and relocalizations holding it now.
  bool paged = false;
  size_t memory_bytes = 0;
};

struct ServerStatus {
  std::vector<SessionStatus> sessions;  // By id.
  int max_sessions = 0;
  int idle_sessions_closed = 0;
  std::vector<LoadedMapStatus> maps;  // By name.
  int map_loads = 0, map_paged_loads = 0, map_cache_hits = 0, map_unloads = 0;
  int workers = 0;       // Frames processed at once at most.
  int workers_busy = 0;  // Now.
  int workers_peak = 0;  // Since the start.
};

}  // namespace visloc::server
