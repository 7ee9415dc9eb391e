#pragma once
// Levenberg-Marquardt refinement of a camera pose from 3D-2D correspondences (seed paper 000,
// eq. 9): minimizes sum_i rho(|| pi(cam_from_world * X_i) - x_i ||^2) over cam_from_world,
// with pi the projection to normalized coordinates and rho the Huber loss. With a rectified
// stereo observation the disparity residual w (B / z_i - (x_left - x_right)) is added, weighted
// by w = sigma_keypoint / sigma_disparity since disparity is measured more precisely than a
// keypoint's position.
//
// Residuals are in normalized units internally; thresholds and reported errors are in pixels
// (normalized * focal_px). The update is a left perturbation T <- exp(delta) T with
// delta = (translation, rotation) in the camera frame; the covariance is in that order too.

#include <algorithm>
#include <limits>
#include <vector>

#include <Eigen/Core>

#include "core/geometry/rigid3.h"

namespace visloc {

struct PoseObservation {
  Eigen::Vector3d point_in_world = Eigen::Vector3d::Zero();
  Eigen::Vector2d normalized = Eigen::Vector2d::Zero();  // Left camera, undistorted (x/z, y/z).
  bool has_right = false;
  double right_x_normalized = 0.0;  // Rectified right camera's x/z (baseline along +x).
  // Pixels per focal length of normalized error at this observation (Camera::PixelScale): 1 for
  // a pinhole; towards a fisheye's rim a pixel spans more normalized units, so its error is
  // weighed down to what it is in the image.
  double pixel_scale = 1.0;
};

struct PoseRefineOptions {
  double focal_px = 1.0;          // Converts normalized residuals to pixels.
  double baseline_m = 0.0;        // Rectified stereo baseline, for right observations.
  double disparity_weight = 1.0;  // Weight of the disparity residual (see above).
  double huber_px = 2.0;          // Huber threshold.
  double pixel_sigma_px = 1.0;    // Measurement noise, for the covariance.
  int max_iterations = 10;
  void Check() const;
};

struct PoseRefineStats {
  int iterations = 0;
  double initial_rmse_px = 0.0;
  double final_rmse_px = 0.0;
  bool converged = false;
};

// Returns the refined cam_from_world. `covariance` (6x6, translation m then rotation rad) is
// sigma^2 (J^T J)^-1 at the optimum. Needs at least 3 observations (else returns the input).
Rigid3d RefinePose(const Rigid3d& cam_from_world, const std::vector<PoseObservation>& observations,
                   const PoseRefineOptions& options, PoseRefineStats* stats = nullptr,
                   Eigen::Matrix<double, 6, 6>* covariance = nullptr);

// Observations made by a rig of cameras mounted rigidly together, whose pose is its reference
// camera's: camera c's observations are in its own normalized coordinates, and cam_from_ref[c]
// places it on the rig (cam_from_ref[0] is the identity when camera 0 is the reference).
struct RigObservations {
  std::vector<Rigid3d> cam_from_ref;
  std::vector<std::vector<PoseObservation>> per_camera;  // One set per camera (mono only).
  size_t size() const;                                   // Over all cameras.
};

// RefinePose over a rig: the reference camera's pose from every camera's observations; the
// update is a left perturbation in the reference camera's frame, and so is the covariance.
// Right (stereo) observations are not used.
Rigid3d RefineRigPose(const Rigid3d& ref_from_world, const RigObservations& rig,
                      const PoseRefineOptions& options, PoseRefineStats* stats = nullptr,
                      Eigen::Matrix<double, 6, 6>* covariance = nullptr);

// The adjoint of `b_from_a` for left perturbations, translation first: b_from_a * exp(delta) =
// exp(PoseAdjoint(b_from_a) * delta) * b_from_a. It moves a pose's perturbation (and, as
// Ad^T H Ad, its information) from frame a to frame b.
Eigen::Matrix<double, 6, 6> PoseAdjoint(const Rigid3d& b_from_a);

// A pose in matrix form for evaluating many observations: the quaternion is converted once
// rather than rotating every point by it (about half the arithmetic per point).
class PoseProjector {
 public:
  PoseProjector(const Rigid3d& cam_from_world, const PoseRefineOptions& options)
      : rotation_(cam_from_world.rotation.toRotationMatrix()),
        translation_(cam_from_world.translation),
        focal_sq_(options.focal_px * options.focal_px),
        baseline_m_(options.baseline_m),
        disparity_weight_(options.disparity_weight) {}

  Eigen::Vector3d ToCamera(const Eigen::Vector3d& point_in_world) const {
    return rotation_ * point_in_world + translation_;
  }
  // Squared error in pixels^2 of one observation: the larger of the left image reprojection
  // error and the weighted disparity error; infinite behind the camera.
  double SquaredErrorPx(const PoseObservation& o) const {
    const Eigen::Vector3d p = ToCamera(o.point_in_world);
    if (p.z() <= 1e-6) return std::numeric_limits<double>::infinity();
    const double iz = 1.0 / p.z();
    const double ex = p.x() * iz - o.normalized.x(), ey = p.y() * iz - o.normalized.y();
    double squared = (ex * ex + ey * ey) * (o.pixel_scale * o.pixel_scale);
    if (o.has_right) {
      const double ed =
          disparity_weight_ * (baseline_m_ * iz - (o.normalized.x() - o.right_x_normalized));
      squared = std::max(squared, ed * ed);
    }
    return squared * focal_sq_;
  }

 private:
  Eigen::Matrix3d rotation_;
  Eigen::Vector3d translation_;
  double focal_sq_, baseline_m_, disparity_weight_;
};

}  // namespace visloc
