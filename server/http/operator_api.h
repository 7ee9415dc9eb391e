#pragma once
// The JSON the operator's page reads (server/http/page/index.html), built from the server's
// plain status types: the live sessions (the same registry as the Fleet service and /metrics),
// the maps of the folder, and a map's top view. Times are seconds relative to the server's now,
// so the page needs no clock of its own; nothing names a server path.

#include <chrono>
#include <string>
#include <vector>

#include "core/localization/localizability.h"
#include "server/server_status.h"

namespace visloc::server {

// {"max_sessions","load":{"busy_fraction","wait_p95_ms","frames_per_s","admit_busy_fraction",
//  "projected_busy_fraction","refused_at_capacity"},
//  "sessions":[{"session","robot","map","status","has_pose","x","y","z","yaw_deg",...}]}
std::string SessionsJson(const ServerStatus& status, std::chrono::system_clock::time_point now);
// {"maps":[{"name","file_bytes","keyframes","points","problem"}]}
std::string MapsJson(const std::vector<MapSummary>& maps);
// {"name","frame","frame_how","total_keyframes","total_points","site_from_map":[12, row-major
//  3x4, when frame is not "map"],"keyframes":[x,y,x,y,...],"points":[...]}
std::string TopViewJson(const MapTopView& view);
// {"map","frame","min_x","min_y","cell","cells_x","cells_y","headings","height_m","pitch_deg",
//  "good_poses","best":[per cell: the best heading's expected inliers],"good":[per cell: good
//  headings]}, cells row by row from min_y.
std::string LocalizabilityJson(const LocalizabilityReport& report);
// {"map","problem"}: why the map has no grid (no level frame, more poses than a request may ask).
std::string LocalizabilityProblemJson(const std::string& map, const std::string& problem);
// {"jobs":[{"job","map","robot","state","running","frames","keyframes","points","has_pose",
//  "x","z","yaw_deg","keyframes_xz":[x,z,...],"points_xz":[...]}]}
std::string MappingJobsJson(const std::vector<MappingJobView>& jobs);

}  // namespace visloc::server
