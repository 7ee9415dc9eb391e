#include "mapping/map_update.h"

#include <cmath>

#include "core/util/check.h"
#include "mapping/point_grid.h"

namespace visloc::mapping {
namespace {

// The session's reconstructed points per keyframe, in the map frame.
class SessionPoints {
 public:
  SessionPoints(const Map& session, const Rigid3d& map_from_session, double cell_m)
      : grid_(cell_m) {
    for (const Observation& o : session.observations) {
      grid_.Add(map_from_session * session.points[o.point].position_in_map,
                static_cast<int>(o.keyframe));
    }
  }

  // Whether keyframe `keyframe` reconstructed a point within `radius_m` (<= the cell) of `p`.
  bool Saw(int keyframe, const Eigen::Vector3d& p, double radius_m) const {
    bool saw = false;
    grid_.ForEachWithin(p, radius_m, [&](int k, const Eigen::Vector3d&) { saw |= k == keyframe; });
    return saw;
  }

 private:
  PointGrid grid_;  // Ids are the observing keyframes.
};

// The mean direction (unit) from which the map's keyframes saw each point.
std::vector<Eigen::Vector3d> ViewDirections(const Map& map) {
  std::vector<Eigen::Vector3d> direction(map.points.size(), Eigen::Vector3d::Zero());
  for (const Observation& o : map.observations) {
    const Eigen::Vector3d ray =
        map.points[o.point].position_in_map - map.keyframes[o.keyframe].map_from_cam.translation;
    if (ray.norm() > 1e-9) direction[o.point] += ray.normalized();
  }
  for (Eigen::Vector3d& d : direction) {
    if (d.norm() > 1e-9) d.normalize();
  }
  return direction;
}

}  // namespace

void UpdateOptions::Check() const {
  merge.Check();
  if (min_expected_views < 1) throw CheckError("a point must be expected in at least one view");
  if (!(found_distance_m > 0) || !(max_depth_m > 0)) throw CheckError("distances must be positive");
  if (!(max_view_angle_deg > 0 && max_view_angle_deg <= 180))
    throw CheckError("the view angle is 0 to 180 deg");
}

Map UpdateMap(const Map& map, const Map& session, const UpdateOptions& options, UpdateStats* stats,
              const std::optional<Rigid3d>& map_from_session_guess) {
  options.Check();
  *stats = UpdateStats{};
  MergeStats registration;
  const Rigid3d map_from_session =
      RegisterMaps(map, session, options.merge, &registration, map_from_session_guess);
  const SessionPoints seen(session, map_from_session, options.found_distance_m);
  std::vector<Rigid3d> cam_from_map;
  for (const Keyframe& k : session.keyframes)
    cam_from_map.push_back((map_from_session * k.map_from_cam).Inverse());
  const std::vector<Eigen::Vector3d> directions = ViewDirections(map);
  const double min_cos = std::cos(options.max_view_angle_deg * M_PI / 180.0);
  std::vector<bool> remove(map.points.size(), false);
  for (size_t p = 0; p < map.points.size(); ++p) {
    const Eigen::Vector3d& x = map.points[p].position_in_map;
    int expected = 0, found = 0;
    for (size_t k = 0; k < cam_from_map.size(); ++k) {
      const Eigen::Vector3d in_cam = cam_from_map[k] * x;
      if (in_cam.z() < 0.1 || in_cam.norm() > options.max_depth_m) continue;
      Eigen::Vector2d pixel;
      if (!map.camera.Project(in_cam, &pixel) ||
          !map.camera.IsInImage(pixel, options.image_margin_px))
        continue;
      const Eigen::Vector3d ray = (x - cam_from_map[k].Inverse().translation).normalized();
      if (ray.dot(directions[p]) < min_cos) continue;
      ++expected;
      if (seen.Saw(static_cast<int>(k), x, options.found_distance_m)) ++found;
    }
    if (expected < options.min_expected_views) continue;
    ++stats->checked_points;
    if (found == 0) {
      remove[p] = true;
      ++stats->removed_points;
    }
  }
  // What remains of the map is where it was: the registration holds, and the merge only refines
  // it with the points that are left.
  Map updated = MergeMaps(WithoutPoints(map, remove), session, options.merge, &stats->merge,
                          map_from_session);
  updated.metadata.lineage = MergedLineage(map.metadata, session.metadata, "update");
  return updated;
}

}  // namespace visloc::mapping
