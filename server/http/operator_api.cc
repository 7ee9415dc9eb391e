#include "server/http/operator_api.h"

#include <algorithm>
#include <cmath>

#include "core/localization/localizer.h"
#include "core/util/json.h"

namespace visloc::server {
namespace {

double SecondsBetween(std::chrono::system_clock::time_point from,
                      std::chrono::system_clock::time_point to) {
  return std::chrono::duration<double>(to - from).count();
}

// The camera's heading seen from above: the angle of its viewing direction (z) in the x-z plane,
// degrees, 0 along the map's z.
double YawDeg(const Rigid3d& map_from_cam) {
  const Eigen::Vector3d forward = map_from_cam.rotation * Eigen::Vector3d::UnitZ();
  return std::atan2(forward.x(), forward.z()) * 180.0 / M_PI;
}

void Pairs(JsonWriter& json, const std::vector<std::pair<float, float>>& xz) {
  json.BeginArray();
  for (const auto& [x, z] : xz) {
    // Millimetres are plenty for drawing, and keep the answer small.
    json.Value(std::round(x * 1000.0) / 1000.0).Value(std::round(z * 1000.0) / 1000.0);
  }
  json.EndArray();
}

}  // namespace

std::string SessionsJson(const ServerStatus& status, std::chrono::system_clock::time_point now) {
  JsonWriter json;
  // The workers' load and admission control (admission.h), for the page's header.
  const WorkerLoadStats& load = status.worker_load;
  json.BeginObject()
      .Field("max_sessions", status.max_sessions)
      .Key("load")
      .BeginObject()
      .Field("busy_fraction", load.busy_fraction)
      .Field("wait_p95_ms", load.wait_p95_ms)
      .Field("frames_per_s", load.frames_per_s)
      .Field("admit_busy_fraction", status.admit_busy_fraction)
      .Field("projected_busy_fraction", status.projected_busy_fraction)
      .Field("refused_at_capacity", status.sessions_refused_at_capacity)
      .EndObject()
      .Key("sessions")
      .BeginArray();
  for (const SessionStatus& s : status.sessions) {
    json.BeginObject()
        .Field("session", s.id)
        .Field("robot", s.robot_id)
        .Field("map", s.map)
        .Field("status", std::string(TrackingStatusName(s.status)))
        .Field("has_pose", s.has_pose);
    if (s.has_pose) {
      const Eigen::Vector3d& t = s.map_from_cam.translation;
      json.Field("x", t.x())
          .Field("y", t.y())
          .Field("z", t.z())
          .Field("yaw_deg", YawDeg(s.map_from_cam))
          .Field("position_sigma_m", s.position_sigma_m);
      // The optical axis in the map frame, for a page drawing the map's level frame.
      const Eigen::Vector3d forward = s.map_from_cam.rotation * Eigen::Vector3d::UnitZ();
      json.Key("forward").BeginArray().Value(forward.x()).Value(forward.y()).Value(forward.z());
      json.EndArray();
    }
    json.Field("inliers", s.inliers).Key("camera_inliers").BeginArray();
    for (int inliers : s.camera_inliers) json.Value(static_cast<int64_t>(inliers));
    json.EndArray().Key("camera_names").BeginArray();
    for (const std::string& name : s.camera_names) json.Value(name);
    json.EndArray()
        .Field("inlier_ratio", s.inlier_ratio)
        .Field("server_ms", s.server_ms)
        .Field("frame_rate_hz", s.frame_rate_hz)
        .Field("frames", s.frames)
        .Field("localized", s.localized)
        .Field("skipped", s.skipped)
        .Field("errors", s.errors)
        .Field("seconds_since_start", SecondsBetween(s.started, now))
        .Field("seconds_since_frame", s.frames ? SecondsBetween(s.last_frame, now) : -1.0)
        .Field("seconds_without_pose",
               s.without_pose_since ? SecondsBetween(*s.without_pose_since, now) : 0.0)
        .EndObject();
  }
  json.EndArray().EndObject();
  return json.str();
}

std::string MapsJson(const std::vector<MapSummary>& maps) {
  JsonWriter json;
  json.BeginObject().Key("maps").BeginArray();
  for (const MapSummary& m : maps) {
    json.BeginObject()
        .Field("name", m.name)
        .Field("file_bytes", m.file_bytes)
        .Field("keyframes", m.keyframes)
        .Field("points", m.points)
        .Field("problem", m.problem)
        .EndObject();
  }
  json.EndArray().EndObject();
  return json.str();
}

std::string TopViewJson(const MapTopView& view) {
  JsonWriter json;
  json.BeginObject()
      .Field("name", view.name)
      .Field("frame", view.frame)
      .Field("frame_how", view.frame_how)
      .Field("total_keyframes", view.total_keyframes)
      .Field("total_points", view.total_points);
  if (view.frame != "map") {  // Row-major 3x4 [R | t]: the page turns robots' poses with it.
    const Eigen::Matrix3d r = view.site_from_map.rotation.toRotationMatrix();
    json.Key("site_from_map").BeginArray();
    for (int row = 0; row < 3; ++row) {
      for (int col = 0; col < 3; ++col) json.Value(r(row, col));
      json.Value(view.site_from_map.translation[row]);
    }
    json.EndArray();
  }
  json.Key("keyframes");
  Pairs(json, view.keyframes);
  json.Key("points");
  Pairs(json, view.points);
  json.EndObject();
  return json.str();
}

std::string MappingJobsJson(const std::vector<MappingJobView>& jobs) {
  JsonWriter json;
  json.BeginObject().Key("jobs").BeginArray();
  for (const MappingJobView& j : jobs) {
    json.BeginObject()
        .Field("job", j.id)
        .Field("map", j.map)
        .Field("robot", j.robot_id)
        .Field("state", j.state)
        .Field("running", j.running)
        .Field("frames", j.frames)
        .Field("keyframes", j.keyframes)
        .Field("points", j.points)
        .Field("has_pose", j.has_pose);
    if (j.has_pose) {
      json.Field("x", j.map_from_cam.translation.x())
          .Field("z", j.map_from_cam.translation.z())
          .Field("yaw_deg", YawDeg(j.map_from_cam));
    }
    json.Key("keyframes_xz");
    Pairs(json, j.keyframes_xz);
    json.Key("points_xz");
    Pairs(json, j.points_xz);
    json.EndObject();
  }
  json.EndArray().EndObject();
  return json.str();
}

std::string LocalizabilityJson(const LocalizabilityReport& report) {
  const LocalizabilityGrid& grid = report.grid;
  JsonWriter json;
  json.BeginObject()
      .Field("map", report.map)
      .Field("frame", report.frame)
      .Field("min_x", grid.min_x_m)
      .Field("min_y", grid.min_y_m)
      .Field("cell", grid.cell_m)
      .Field("cells_x", grid.cells_x)
      .Field("cells_y", grid.cells_y)
      .Field("headings", grid.headings)
      .Field("height_m", grid.height_m)
      .Field("pitch_deg", grid.pitch_deg)
      .Field("good_poses", report.stats.good_poses);
  // Per cell (iy * cells_x + ix): the best heading's expected inliers, and how many headings
  // are good, in one pass over the grid.
  std::vector<int64_t> best, good;
  for (int iy = 0; iy < grid.cells_y; ++iy) {
    for (int ix = 0; ix < grid.cells_x; ++ix) {
      float cell_best = 0.0f;
      int64_t cell_good = 0;
      for (int h = 0; h < grid.headings; ++h) {
        cell_best = std::max(cell_best, grid.at(ix, iy, h).expected_inliers);
        cell_good += grid.at(ix, iy, h).good ? 1 : 0;
      }
      best.push_back(std::lround(cell_best));
      good.push_back(cell_good);
    }
  }
  json.Key("best").BeginArray();
  for (int64_t value : best) json.Value(value);
  json.EndArray().Key("good").BeginArray();
  for (int64_t value : good) json.Value(value);
  json.EndArray().EndObject();
  return json.str();
}

std::string LocalizabilityProblemJson(const std::string& map, const std::string& problem) {
  JsonWriter json;
  json.BeginObject().Field("map", map).Field("problem", problem).EndObject();
  return json.str();
}

}  // namespace visloc::server
