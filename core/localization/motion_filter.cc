#include "core/localization/motion_filter.h"

#include <cmath>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include "core/util/check.h"

namespace visloc {
Rigid3d ExpSe3(const Vector6d& tangent) {
  const Eigen::Vector3d phi = tangent.tail<3>();
  const double angle = phi.norm();
  const Eigen::Quaterniond rotation =
      angle > 1e-12 ? Eigen::Quaterniond(Eigen::AngleAxisd(angle, phi / angle))
                    : Eigen::Quaterniond::Identity();
  return Rigid3d(rotation, tangent.head<3>());
}

Vector6d LogSe3(const Rigid3d& transform) {
  const Eigen::AngleAxisd angle_axis(transform.rotation);
  Vector6d tangent;
  tangent << transform.translation, angle_axis.angle() * angle_axis.axis();
  return tangent;
}

Matrix6d Adjoint(const Rigid3d& transform) {
  const Eigen::Matrix3d r = transform.rotation.toRotationMatrix();
  Matrix6d adjoint = Matrix6d::Zero();
  adjoint.topLeftCorner<3, 3>() = r;
  adjoint.topRightCorner<3, 3>() = Skew(transform.translation) * r;
  adjoint.bottomRightCorner<3, 3>() = r;
  return adjoint;
}

void MotionFilter::Reset(const Rigid3d& map_from_cam, const Matrix6d& covariance) {
  VISLOC_CHECK(covariance.allFinite(), "non-finite covariance");
  map_from_cam_ = map_from_cam;
  covariance_ = 0.5 * (covariance + covariance.transpose());
  initialized_ = true;
}

void MotionFilter::Predict(const Rigid3d& cam_prev_from_cam_cur, const Matrix6d& process_noise) {
  VISLOC_CHECK(initialized_, "MotionFilter::Predict before Reset");
  const Matrix6d a = Adjoint(cam_prev_from_cam_cur.Inverse());
  map_from_cam_ = map_from_cam_ * cam_prev_from_cam_cur;
  map_from_cam_.rotation.normalize();
  covariance_ = a * covariance_ * a.transpose() + process_noise;
}

double MotionFilter::UpdatePose(const Rigid3d& measured, const Matrix6d& noise) {
  VISLOC_CHECK(initialized_, "MotionFilter::UpdatePose before Reset");
  const Vector6d innovation = Innovation(measured);
  const Matrix6d s = covariance_ + noise;
  const Eigen::LDLT<Matrix6d> s_ldlt = s.ldlt();
  // K = P S^-1 (S and P symmetric).
  const Matrix6d gain = s_ldlt.solve(covariance_).transpose();
  map_from_cam_ = map_from_cam_ * ExpSe3(gain * innovation);
  map_from_cam_.rotation.normalize();
  const Matrix6d i_minus_k = Matrix6d::Identity() - gain;
  // Joseph form keeps the covariance symmetric and positive definite.
  covariance_ = i_minus_k * covariance_ * i_minus_k.transpose() + gain * noise * gain.transpose();
  return innovation.dot(s_ldlt.solve(innovation));
}

Vector6d MotionFilter::Innovation(const Rigid3d& measured) const {
  return LogSe3(map_from_cam_.Inverse() * measured);
}

double MotionFilter::InnovationDistanceSq(const Rigid3d& measured, const Matrix6d& noise) const {
  VISLOC_CHECK(initialized_, "MotionFilter::InnovationDistanceSq before Reset");
  const Vector6d innovation = Innovation(measured);
  return innovation.dot((covariance_ + noise).ldlt().solve(innovation));
}

void MotionFilter::UpdateHeight(const Eigen::Vector3d& normal, double offset, double height_m,
                                double sigma_m) {
  VISLOC_CHECK(initialized_, "MotionFilter::UpdateHeight before Reset");
  VISLOC_CHECK(sigma_m > 0, "height sigma ", sigma_m);
  const double residual = height_m - (normal.dot(map_from_cam_.translation) - offset);
  // d(normal . t) / d rho = normal^T R (the perturbation is in the camera frame).
  Eigen::Matrix<double, 1, 6> h = Eigen::Matrix<double, 1, 6>::Zero();
  h.head<3>() = normal.transpose() * map_from_cam_.rotation.toRotationMatrix();
  const double s = (h * covariance_ * h.transpose())(0, 0) + sigma_m * sigma_m;
  const Vector6d gain = covariance_ * h.transpose() / s;
  map_from_cam_ = map_from_cam_ * ExpSe3(gain * residual);
  const Matrix6d i_minus_kh = Matrix6d::Identity() - gain * h;
  covariance_ = i_minus_kh * covariance_ * i_minus_kh.transpose() +
                gain * gain.transpose() * sigma_m * sigma_m;
}

double MotionFilter::PositionSigmaM() const {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(covariance_.topLeftCorner<3, 3>());
  return std::sqrt(std::max(0.0, solver.eigenvalues().maxCoeff()));
}

}  // namespace visloc
