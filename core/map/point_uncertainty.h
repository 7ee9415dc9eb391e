#pragma once
// How well the mapping knows each map point's position: a 3x3 covariance in the map frame (m^2)
// from the keyframes that observed it, each one a stereo observation of the rig the map was built
// with (map.h: MapMetadata::stereo_baseline_m).
//
// An observation from keyframe k, at distance d along the unit ray n from the camera's centre to
// the point, pins the point across the ray to d * keypoint_sigma_px / f and along it to the
// stereo depth's sigma z^2 disparity_sigma_px / (f b), stretched by d / z off the optical axis.
// Their information matrices add over the keyframes: a point that every keyframe saw head-on
// from a few metres is known well across its rays and poorly along them, and a query that sees
// it from the side sees that depth error as an error in the image (PoseTracker's systematic
// covariance). The observations are taken as independent: the keyframes' own pose errors are
// the map error the localizer counts apart (PoseTrackerOptions::map_error_px and after).

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "core/map/map.h"

namespace visloc {

struct PointUncertaintyOptions {
  // Noise of a mapped keypoint (the map camera's raw pixels) and of a stereo disparity (px). The
  // keypoint's is what global bundle adjustment leaves (0.46 px rms on the generated square). The
  // disparity's is what the map's depths are worth rather than the rectified disparity's own
  // noise (0.04 px rms there): with 0.1 px, a walk facing out of the mapped square (sim
  // `outward`) had 9% of its frames beyond 3 sigma; with 0.3 px, none. Measured on the
  // generated walks (docs/benchmarks.md) and the real recordings (docs/real-world.md).
  double keypoint_sigma_px = 0.5;
  double disparity_sigma_px = 0.3;
  // A point no observation pins down along its ray (no baseline) keeps this sigma (m) there.
  double max_sigma_m = 10.0;
  void Check() const;
};

// A symmetric 3x3 covariance (m^2, map frame) as its upper triangle, xx xy xz yy yz zz, in
// single precision: 24 bytes a point.
using PointCovariance = Eigen::Matrix<float, 6, 1>;
Eigen::Matrix3d Unpack(const PointCovariance& packed);
PointCovariance Pack(const Eigen::Matrix3d& covariance);
// covariance * v, read from the packed triangle.
inline Eigen::Vector3d SymmetricTimes(const PointCovariance& c, const Eigen::Vector3d& v) {
  return {c[0] * v.x() + c[1] * v.y() + c[2] * v.z(), c[1] * v.x() + c[3] * v.y() + c[4] * v.z(),
          c[2] * v.x() + c[4] * v.y() + c[5] * v.z()};
}

// One covariance per point of `map` (which holds its points and observations), for a rig of
// stereo baseline `baseline_m` (0: observations pin points across their rays only).
std::vector<PointCovariance> PointCovariances(const Map& map, double baseline_m,
                                              const PointUncertaintyOptions& options = {});

}  // namespace visloc
