#include "mapping/map_adjustment.h"

#include <algorithm>
#include <cmath>

#include <ceres/ceres.h>

#include "core/util/check.h"
#include "core/util/timer.h"
#include "mapping/reprojection_cost.h"

namespace visloc::mapping {
namespace {

// Keeps a point near where its own map's stereo bundle adjustment put it: the stereo depth
// the map's mono observations no longer carry. sigma grows with depth squared, as a stereo
// depth's does.
class PointPriorCost {
 public:
  PointPriorCost(const Eigen::Vector3d& prior, double sigma_m) : prior_(prior), sigma_m_(sigma_m) {}
  template <typename T>
  bool operator()(const T* point, T* residuals) const {
    for (int i = 0; i < 3; ++i) residuals[i] = (point[i] - T(prior_[i])) / T(sigma_m_);
    return true;
  }
  static ceres::CostFunction* Create(const Eigen::Vector3d& prior, double sigma_m) {
    return new ceres::AutoDiffCostFunction<PointPriorCost, 3, 3>(
        new PointPriorCost(prior, sigma_m));
  }

 private:
  Eigen::Vector3d prior_;
  double sigma_m_;
};

// Raw-pixel reprojection error of observation `o`; large when behind the camera.
double ReprojectionErrorPx(const Map& map, const Observation& o) {
  const Eigen::Vector3d in_cam =
      map.keyframes[o.keyframe].map_from_cam.Inverse() * map.points[o.point].position_in_map;
  Eigen::Vector2d pixel;
  if (!map.camera.Project(in_cam, &pixel)) return 1e6;
  return (pixel - o.pixel.cast<double>()).norm();
}

// RMSE over the observations flagged in `used`, each error capped at 10 px so that a few wild
// outliers (which the Huber loss discounts too) do not hide what happened to the rest.
double RmsePx(const Map& map, const std::vector<bool>& used) {
  double sum_sq = 0.0;
  int n = 0;
  for (size_t i = 0; i < map.observations.size(); ++i) {
    if (!used[i]) continue;
    const double e = std::min(ReprojectionErrorPx(map, map.observations[i]), 10.0);
    sum_sq += e * e;
    ++n;
  }
  return n ? std::sqrt(sum_sq / n) : 0.0;
}

// Points whose observations reach a free keyframe: adjusted when seen at least twice, carried
// along by their keyframe when seen once (the owner, else -1).
struct PointRoles {
  std::vector<bool> adjusted;
  std::vector<int> carrier;
};

PointRoles AssignRoles(const Map& map, const std::vector<bool>& keyframe_fixed) {
  PointRoles roles{std::vector<bool>(map.points.size(), false),
                   std::vector<int>(map.points.size(), -1)};
  std::vector<bool> seen_by_free(map.points.size(), false);
  for (const Observation& o : map.observations) {
    if (!keyframe_fixed[o.keyframe]) seen_by_free[o.point] = true;
  }
  for (const Observation& o : map.observations) {
    if (!seen_by_free[o.point]) continue;
    if (map.points[o.point].observation_count >= 2) {
      roles.adjusted[o.point] = true;
    } else {
      roles.carrier[o.point] = static_cast<int>(o.keyframe);
    }
  }
  return roles;
}

// A prior for every adjusted point at its current position; sigma from the depth at which the
// first keyframe that sees it sees it.
void AddPointPriors(Map* map, const PointRoles& roles, const MapAdjustmentOptions& options,
                    ceres::Problem* problem, MapAdjustmentStats* stats) {
  if (!(options.point_prior_sigma_at_1m_m > 0)) return;
  std::vector<double> depth_m(map->points.size(), 0.0);
  for (const Observation& o : map->observations) {
    if (depth_m[o.point] != 0.0) continue;
    const Rigid3d cam_from_map = map->keyframes[o.keyframe].map_from_cam.Inverse();
    depth_m[o.point] = (cam_from_map * map->points[o.point].position_in_map).z();
  }
  for (size_t p = 0; p < map->points.size(); ++p) {
    if (!roles.adjusted[p]) continue;
    const double z = std::max(1.0, depth_m[p]);
    Eigen::Vector3d& position = map->points[p].position_in_map;
    problem->AddResidualBlock(
        PointPriorCost::Create(position, options.point_prior_sigma_at_1m_m * z * z), nullptr,
        position.data());
    ++stats->point_priors;
  }
}

// Of the adjusted observations (`used`), those still above the threshold go; the map's other
// observations are left as their own adjustment made them.
void CullObservations(Map* map, const std::vector<bool>& used, double cull_error_px,
                      MapAdjustmentStats* stats) {
  if (!(cull_error_px > 0)) return;
  std::vector<Observation> kept;
  for (size_t i = 0; i < map->observations.size(); ++i) {
    const Observation& o = map->observations[i];
    if (!used[i] || ReprojectionErrorPx(*map, o) <= cull_error_px) kept.push_back(o);
  }
  stats->culled_observations = static_cast<int>(map->observations.size() - kept.size());
  map->observations = std::move(kept);
  CountObservations(map);
  std::vector<bool> unseen(map->points.size(), false);
  for (size_t p = 0; p < map->points.size(); ++p) unseen[p] = map->points[p].observation_count == 0;
  stats->culled_points = static_cast<int>(std::count(unseen.begin(), unseen.end(), true));
  if (stats->culled_points > 0) *map = WithoutPoints(*map, unseen);
}

void UpdateMeanErrors(Map* map) {
  std::vector<double> sum(map->points.size(), 0.0);
  for (const Observation& o : map->observations) sum[o.point] += ReprojectionErrorPx(*map, o);
  for (size_t p = 0; p < map->points.size(); ++p) {
    if (map->points[p].observation_count > 0) {
      map->points[p].mean_reproj_error_px =
          static_cast<float>(sum[p] / map->points[p].observation_count);
    }
  }
}

}  // namespace

MapAdjustmentStats AdjustMap(Map* map, const std::vector<bool>& keyframe_fixed,
                             const MapAdjustmentOptions& options) {
  VISLOC_CHECK(keyframe_fixed.size() == map->keyframes.size(), "one flag per keyframe");
  VISLOC_CHECK(std::count(keyframe_fixed.begin(), keyframe_fixed.end(), true) > 0,
               "at least one keyframe must be held fixed: it fixes the map frame");
  Timer timer;
  MapAdjustmentStats stats;
  stats.fixed_keyframes =
      static_cast<int>(std::count(keyframe_fixed.begin(), keyframe_fixed.end(), true));
  stats.free_keyframes = static_cast<int>(keyframe_fixed.size()) - stats.fixed_keyframes;
  const PointRoles roles = AssignRoles(*map, keyframe_fixed);
  const std::vector<Rigid3d> map_from_cam_before = [&] {
    std::vector<Rigid3d> poses;
    for (const Keyframe& k : map->keyframes) poses.push_back(k.map_from_cam);
    return poses;
  }();

  std::vector<PoseBlock> poses;
  for (const Keyframe& k : map->keyframes) poses.push_back(ToPoseBlock(k.map_from_cam.Inverse()));
  ceres::Problem problem;
  ceres::LossFunction* loss = new ceres::HuberLoss(options.huber_px);  // Shared, owned by problem.
  // Residuals on the normalized plane scaled by fx: a pinhole of focal fx centred at 0.
  const RectifiedIntrinsics normalized_plane{map->camera.fx(), 0.0, 0.0, 0.0};
  std::vector<bool> used(map->observations.size(), false);
  for (size_t i = 0; i < map->observations.size(); ++i) {
    const Observation& o = map->observations[i];
    if (!roles.adjusted[o.point]) continue;
    const Eigen::Vector3d ray = map->camera.Unproject(o.pixel.cast<double>());
    if (!ray.allFinite()) continue;
    double* pose = poses[o.keyframe].data();
    problem.AddResidualBlock(
        MonoReprojectionCost::Create(map->camera.fx() * ray.head<2>(), normalized_plane), loss,
        pose, pose + 4, map->points[o.point].position_in_map.data());
    used[i] = true;
  }
  stats.residual_blocks = problem.NumResidualBlocks();
  stats.points = static_cast<int>(std::count(roles.adjusted.begin(), roles.adjusted.end(), true));
  stats.initial_rmse_px = RmsePx(*map, used);
  if (stats.residual_blocks == 0) return stats;
  AddPointPriors(map, roles, options, &problem, &stats);
  for (size_t k = 0; k < poses.size(); ++k) SetUpPoseBlock(&problem, &poses[k], keyframe_fixed[k]);
  stats.iterations = SolveQuietly(&problem, ceres::SPARSE_SCHUR, options.max_iterations);

  for (size_t k = 0; k < poses.size(); ++k) {
    if (!keyframe_fixed[k]) map->keyframes[k].map_from_cam = FromPoseBlock(poses[k]).Inverse();
  }
  for (size_t p = 0; p < map->points.size(); ++p) {
    const int k = roles.carrier[p];
    if (k < 0 || keyframe_fixed[k]) continue;
    // Same place in its keyframe's camera as before.
    map->points[p].position_in_map =
        map->keyframes[k].map_from_cam *
        (map_from_cam_before[k].Inverse() * map->points[p].position_in_map);
    ++stats.moved_with_keyframe;
  }
  stats.final_rmse_px = RmsePx(*map, used);
  CullObservations(map, used, options.cull_error_px, &stats);
  UpdateMeanErrors(map);
  stats.time_ms = timer.ElapsedMs();
  return stats;
}

}  // namespace visloc::mapping
