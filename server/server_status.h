#pragma once
// What the server is doing now, as plain values with no transport types: the live sessions, the
// maps and their cache, the worker permits. One snapshot serves every reader (the log, tests,
// and the operator's page and metrics to come), so they never disagree.

#include <chrono>
#include <cstdint>
#include <iterator>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "core/geometry/rigid3.h"
#include "core/localization/localizer.h"
#include "server/worker_load.h"

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
  // A rig session: each camera's inliers in the last answer (0: that camera saw nothing the
  // fix took); empty for one camera.
  std::vector<int> camera_inliers;
  std::vector<std::string> camera_names;  // The rig's, as its SessionStart names them.
  double server_ms = 0.0;
  double frame_rate_hz = 0.0;  // Arrivals per second over the last few seconds.
  // The cores the session's frames take: its frame rate times its frames' recent CPU time
  // (admission.h); negative until it has answered a few frames.
  double cpu_load = -1.0;
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

// What every session has done since the server started, for the metrics (counters only grow).
// Labels stay bounded: map names and outcomes, never robots.
struct FrameCounters {
  // Upper bounds (s) of the server-time histogram's buckets; +Inf is implicit.
  static constexpr double kSecondsBuckets[] = {0.001, 0.002, 0.005, 0.01, 0.02,
                                               0.05,  0.1,   0.2,   0.5,  1.0};
  struct PerMap {
    std::map<std::string, uint64_t>
        frames;                    // By outcome: a TrackingStatusName, "skipped", "error".
    uint64_t relocalizations = 0;  // Frames that searched the map by appearance.
    uint64_t relocalizations_found = 0;
    uint64_t sessions = 0;  // Started.
  };
  std::map<std::string, PerMap> maps;
  // Server time of answered frames (skipped ones take none): cumulative bucket counts.
  uint64_t seconds_buckets[std::size(kSecondsBuckets)] = {};
  uint64_t seconds_count = 0;
  double seconds_sum = 0.0;
};

// A map of the maps folder, as the operator's page lists it.
struct MapSummary {
  std::string name;
  uint64_t file_bytes = 0;
  int64_t keyframes = 0;
  int64_t points = 0;
  std::string problem;  // Why it does not load (for clients: no server paths); empty when sound.
};

// A map seen from above (the map frame's x and z: its first camera looked along z with y down),
// decimated for drawing: at most the asked numbers of keyframe centres and points.
struct MapTopView {
  std::string name;
  // The level frame it is seen in (mapping::PlanFrame: "site", "level" or "floor", with
  // site_from_map), or "map" for a map with no level frame: then the map's x-z plane.
  std::string frame = "map";
  std::string frame_how;
  Rigid3d site_from_map;
  std::vector<std::pair<float, float>> keyframes;  // (x, y) of the frame, metres; (x, z) for "map".
  std::vector<std::pair<float, float>> points;     // Likewise; none for a map served paged.
  int64_t total_keyframes = 0;
  int64_t total_points = 0;
};

// A mapping job (mapping over the link) as the operator's page draws it: its state and the map
// it has so far from above.
struct MappingJobView {
  uint64_t id = 0;
  std::string map;
  std::string robot_id;
  std::string state;  // tracking, lost, frame_error, finishing, waiting, published, failed, ...
  bool running = false;
  uint64_t frames = 0;
  int64_t keyframes = 0;
  int64_t points = 0;
  bool has_pose = false;
  Rigid3d map_from_cam;  // The left camera as mapped so far, when has_pose.
  std::vector<std::pair<float, float>> keyframes_xz;  // (x, z) in metres.
  std::vector<std::pair<float, float>> points_xz;     // At most a few thousand.
};

struct ServerStatus {
  std::vector<SessionStatus> sessions;  // By id.
  FrameCounters counters;
  // Finished RPCs by (full method name, status code name).
  std::map<std::pair<std::string, std::string>, uint64_t> rpcs;
  int max_sessions = 0;
  int idle_sessions_closed = 0;
  std::vector<LoadedMapStatus> maps;  // By name.
  int map_loads = 0, map_paged_loads = 0, map_cache_hits = 0, map_unloads = 0,
      map_load_failures = 0;
  int workers = 0;       // Frames processed at once at most.
  int workers_busy = 0;  // Now.
  int workers_peak = 0;  // Since the start.
  WorkerLoadStats worker_load;  // Over the last window (worker_load.h).
  // Admission control (admission.h): its limit (0: off), what one more session would make the
  // workers' busy fraction, and the sessions it refused since the start.
  double admit_busy_fraction = 0.0;
  double projected_busy_fraction = 0.0;
  uint64_t sessions_refused_at_capacity = 0;
};

}  // namespace visloc::server
