#include "core/map/point_uncertainty.h"

#include <cmath>

#include <Eigen/Cholesky>

#include "core/util/check.h"

namespace visloc {

void PointUncertaintyOptions::Check() const {
  VISLOC_CHECK(keypoint_sigma_px > 0 && disparity_sigma_px > 0 && max_sigma_m > 0,
               "point uncertainty: keypoint ", keypoint_sigma_px, " px, disparity ",
               disparity_sigma_px, " px, at most ", max_sigma_m, " m");
}

Eigen::Matrix3d Unpack(const PointCovariance& p) {
  Eigen::Matrix3d c;
  c << p[0], p[1], p[2], p[1], p[3], p[4], p[2], p[4], p[5];
  return c;
}

PointCovariance Pack(const Eigen::Matrix3d& c) {
  PointCovariance p;
  p << c(0, 0), c(0, 1), c(0, 2), c(1, 1), c(1, 2), c(2, 2);
  return p;
}

std::vector<PointCovariance> PointCovariances(const Map& map, double baseline_m,
                                              const PointUncertaintyOptions& options) {
  options.Check();
  VISLOC_CHECK(baseline_m >= 0, "stereo baseline ", baseline_m, " m");
  const double focal_px = map.camera.fx();
  // Every point starts with a weak prior, so a point seen once without stereo stays invertible.
  std::vector<Eigen::Matrix3d> information(
      map.points.size(), Eigen::Matrix3d::Identity() / (options.max_sigma_m * options.max_sigma_m));
  for (const Observation& o : map.observations) {
    const Rigid3d& map_from_cam = map.keyframes[o.keyframe].map_from_cam;
    const Eigen::Vector3d ray_in_map =
        map.points[o.point].position_in_map - map_from_cam.translation;
    const double distance_m = ray_in_map.norm();
    const double depth_m = (map_from_cam.rotation.inverse() * ray_in_map).z();
    if (distance_m <= 1e-6 || depth_m <= 1e-6) continue;
    const Eigen::Vector3d n = ray_in_map / distance_m;
    const Eigen::Matrix3d along = n * n.transpose();
    const double across_sigma_m = distance_m * options.keypoint_sigma_px / focal_px;
    information[o.point] += (Eigen::Matrix3d::Identity() - along) / (across_sigma_m * across_sigma_m);
    if (baseline_m > 0) {
      const double depth_sigma_m =
          depth_m * depth_m * options.disparity_sigma_px / (focal_px * baseline_m);
      const double along_sigma_m = depth_sigma_m * distance_m / depth_m;
      information[o.point] += along / (along_sigma_m * along_sigma_m);
    }
  }
  std::vector<PointCovariance> covariances(map.points.size());
  for (size_t i = 0; i < information.size(); ++i) {
    covariances[i] = Pack(information[i].ldlt().solve(Eigen::Matrix3d::Identity()));
  }
  return covariances;
}

}  // namespace visloc
