#pragma once
// An extended Kalman filter over the camera pose, fusing the robot's own motion knowledge with
// visual pose fixes (seed paper 001: the walking pattern generator's motion, the gyro and the
// camera height as measurements).
//
// State: map_from_cam T with a 6x6 covariance over a right perturbation
//   T_true = T * Exp(e),  e = (rho, phi): translation (m) then rotation (rad), camera frame.
// Exp(rho, phi) is (rotation Exp(phi), translation rho), to first order the SE(3) exponential.
// The same ordering is used by the pose refinement's covariance (core/estimators), whose left
// perturbation of cam_from_map equals minus this one, so covariances carry over unchanged.
//
// Prediction applies a relative motion cam_prev_from_cam_cur (from odometry and gyro, or the
// constant-velocity model) with its noise; updates take a full visual pose, or one scalar: the
// camera centre's height above a plane (planar motion / known camera height).

#include <Eigen/Core>

#include "core/geometry/rigid3.h"

namespace visloc {

using Vector6d = Eigen::Matrix<double, 6, 1>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;

// (rho, phi) <-> rigid transform, as defined above.
Rigid3d ExpSe3(const Vector6d& tangent);
Vector6d LogSe3(const Rigid3d& transform);
// Adjoint of T for the (rho, phi) ordering: Exp(Ad(T) e) = T Exp(e) T^-1.
Matrix6d Adjoint(const Rigid3d& transform);

class MotionFilter {
 public:
  void Reset(const Rigid3d& map_from_cam, const Matrix6d& covariance);
  bool initialized() const { return initialized_; }

  // T <- T * cam_prev_from_cam_cur; P <- A P A^T + process_noise, A = Ad(delta^-1).
  void Predict(const Rigid3d& cam_prev_from_cam_cur, const Matrix6d& process_noise);

  // Fuses a measured map_from_cam with covariance `noise` (same perturbation). Returns the
  // squared Mahalanobis distance of the innovation (6 degrees of freedom), for gating.
  double UpdatePose(const Rigid3d& measured_map_from_cam, const Matrix6d& noise);
  // That squared Mahalanobis distance, without the update: how far a fix lies from the
  // prediction, in the two uncertainties together.
  double InnovationDistanceSq(const Rigid3d& measured_map_from_cam, const Matrix6d& noise) const;

  // Fuses "the camera centre is `height_m` above the plane {x : normal . x = offset}" (map
  // frame, unit normal) with standard deviation sigma_m.
  void UpdateHeight(const Eigen::Vector3d& normal, double offset, double height_m, double sigma_m);

  const Rigid3d& map_from_cam() const { return map_from_cam_; }
  const Matrix6d& covariance() const { return covariance_; }
  // 1-sigma position uncertainty (m): sqrt of the largest eigenvalue of the position block.
  double PositionSigmaM() const;

 private:
  // The measurement's difference from the state, in the state's perturbation.
  Vector6d Innovation(const Rigid3d& measured_map_from_cam) const;

  bool initialized_ = false;
  Rigid3d map_from_cam_;
  Matrix6d covariance_ = Matrix6d::Identity();
};

}  // namespace visloc
