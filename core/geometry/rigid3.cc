#include "core/geometry/rigid3.h"

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>

namespace visloc {

Rigid3d Rigid3d::FromMatrix(const Eigen::Matrix<double, 3, 4>& matrix) {
  // Project the rotation block onto SO(3) so text files with few digits still give a valid
  // rotation.
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(matrix.leftCols<3>(),
                                              Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d rotation = svd.matrixU() * svd.matrixV().transpose();
  if (rotation.determinant() < 0) {
    Eigen::Matrix3d u = svd.matrixU();
    u.col(2) *= -1.0;
    rotation = u * svd.matrixV().transpose();
  }
  return Rigid3d(rotation, matrix.col(3));
}

Eigen::Matrix<double, 3, 4> Rigid3d::ToMatrix3x4() const {
  Eigen::Matrix<double, 3, 4> matrix;
  matrix.leftCols<3>() = rotation.toRotationMatrix();
  matrix.col(3) = translation;
  return matrix;
}

Eigen::Matrix4d Rigid3d::ToMatrix4() const {
  Eigen::Matrix4d matrix = Eigen::Matrix4d::Identity();
  matrix.topRows<3>() = ToMatrix3x4();
  return matrix;
}

Rigid3d Rigid3d::Inverse() const {
  const Eigen::Quaterniond inverse_rotation = rotation.conjugate();
  return Rigid3d(inverse_rotation, -(inverse_rotation * translation));
}

Rigid3d Interpolate(const Rigid3d& start, const Rigid3d& end, double t) {
  return Rigid3d(start.rotation.slerp(t, end.rotation),
                 (1.0 - t) * start.translation + t * end.translation);
}

double RotationAngleDeg(const Eigen::Quaterniond& rotation) {
  const Eigen::Quaterniond q = rotation.normalized();
  // atan2 form is accurate for small angles, unlike acos(w).
  const double angle_rad = 2.0 * std::atan2(q.vec().norm(), std::abs(q.w()));
  return angle_rad * 180.0 / M_PI;
}

Eigen::Quaterniond RotationFromRollPitchYaw(double roll, double pitch, double yaw) {
  return Eigen::Quaterniond(Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
                            Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
                            Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()));
}

bool ApproxEqual(const Rigid3d& a, const Rigid3d& b, double translation_tol_m,
                 double rotation_tol_deg) {
  return (a.translation - b.translation).norm() <= translation_tol_m &&
         RotationAngleDeg(a.rotation.conjugate() * b.rotation) <= rotation_tol_deg;
}

}  // namespace visloc
