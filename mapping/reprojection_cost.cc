#include "mapping/reprojection_cost.h"

namespace visloc::mapping {

namespace {

// The pinhole residual (rows 0, 1) of camera point p, and its derivative by p when asked.
void PinholeResidual(const Eigen::Vector3d& p, const Eigen::Vector2d& observed_px,
                     const RectifiedIntrinsics& k, double* residuals,
                     Eigen::Matrix<double, 2, 3>* dr_dp) {
  const double inverse_z = 1.0 / p.z();
  const double u = p.x() * inverse_z, v = p.y() * inverse_z;
  residuals[0] = k.f * u + k.cx - observed_px.x();
  residuals[1] = k.f * v + k.cy - observed_px.y();
  if (dr_dp) {
    const double fz = k.f * inverse_z;
    *dr_dp << fz, 0.0, -fz * u, 0.0, fz, -fz * v;
  }
}

// Row-major Ceres Jacobian block `rows` x `cols` from `m`.
template <int kRows, int kCols>
void WriteJacobian(const Eigen::Matrix<double, kRows, kCols>& m, double* block) {
  using RowMajor = Eigen::Matrix<double, kRows, kCols, Eigen::RowMajor>;
  Eigen::Map<RowMajor> out(block);
  out = m;
}

}  // namespace

void TransformToCamera(const double* rotation, const double* translation, const double* point,
                       bool jacobians, CameraPoint* out) {
  const Eigen::Vector3d v(rotation[0], rotation[1], rotation[2]);
  const double w = rotation[3];
  const Eigen::Vector3d x(point[0], point[1], point[2]);
  const Eigen::Vector3d v_cross_x = v.cross(x);
  out->p = x + 2.0 * w * v_cross_x + 2.0 * v.cross(v_cross_x) +
           Eigen::Vector3d(translation[0], translation[1], translation[2]);
  if (!jacobians) return;
  // d/dv of 2 w (v x X) + 2 (v (v.X) - X (v.v)); d/dw of 2 w (v x X).
  out->dp_drotation.leftCols<3>() = -2.0 * w * Skew(x) +
                                    2.0 * (v.dot(x) * Eigen::Matrix3d::Identity() + v * x.transpose()) -
                                    4.0 * x * v.transpose();
  out->dp_drotation.col(3) = 2.0 * v_cross_x;
  out->dp_dpoint = Eigen::Quaterniond(w, v.x(), v.y(), v.z()).toRotationMatrix();
}

StereoReprojectionCost::StereoReprojectionCost(const Eigen::Vector2d& left_px, double right_x_px,
                                               const RectifiedIntrinsics& k,
                                               double disparity_weight)
    : left_px_(left_px),
      disparity_px_(left_px.x() - right_x_px),
      yaw_gain_px_(k.f * (1.0 + std::pow((right_x_px - k.cx) / k.f, 2))),
      k_(k),
      disparity_weight_(disparity_weight) {}

StereoReprojectionCost* StereoReprojectionCost::LeftOnly(const Eigen::Vector2d& left_px,
                                                         const RectifiedIntrinsics& k) {
  // Any finite right column: with no weight, the disparity row is zero whatever it is.
  return new StereoReprojectionCost(left_px, left_px.x(), k, 0.0);
}

bool StereoReprojectionCost::Evaluate(double const* const* parameters, double* residuals,
                                      double** jacobians) const {
  CameraPoint camera;
  TransformToCamera(parameters[0], parameters[1], parameters[2], jacobians != nullptr, &camera);
  const double* correction = parameters[3];
  Eigen::Matrix<double, 2, 3> pinhole_dp;
  PinholeResidual(camera.p, left_px_, k_, residuals, jacobians ? &pinhole_dp : nullptr);
  const double inverse_z = 1.0 / camera.p.z();
  const double fb = k_.f * k_.baseline_m;
  const double bias = correction[0] + yaw_gain_px_ * correction[1];
  residuals[2] = disparity_weight_ * (fb * inverse_z - disparity_px_ + bias);
  if (!jacobians) return true;
  Eigen::Matrix3d dr_dp;
  dr_dp.topRows<2>() = pinhole_dp;
  dr_dp.row(2) << 0.0, 0.0, -disparity_weight_ * fb * inverse_z * inverse_z;
  if (jacobians[0]) WriteJacobian<3, 4>(dr_dp * camera.dp_drotation, jacobians[0]);
  if (jacobians[1]) WriteJacobian<3, 3>(dr_dp, jacobians[1]);
  if (jacobians[2]) WriteJacobian<3, 3>(dr_dp * camera.dp_dpoint, jacobians[2]);
  if (jacobians[3]) {
    Eigen::Matrix<double, 3, kCorrectionBlockSize> dr_dcorrection =
        Eigen::Matrix<double, 3, kCorrectionBlockSize>::Zero();
    dr_dcorrection.row(2) << disparity_weight_, disparity_weight_ * yaw_gain_px_, 0.0;
    WriteJacobian<3, kCorrectionBlockSize>(dr_dcorrection, jacobians[3]);
  }
  return true;
}

bool StereoReprojectionCost::operator()(const double* rotation, const double* translation,
                                        const double* point, const double* correction,
                                        double* residuals) const {
  const double* parameters[] = {rotation, translation, point, correction};
  return Evaluate(parameters, residuals, nullptr);
}

bool MonoReprojectionCost::Evaluate(double const* const* parameters, double* residuals,
                                    double** jacobians) const {
  CameraPoint camera;
  TransformToCamera(parameters[0], parameters[1], parameters[2], jacobians != nullptr, &camera);
  Eigen::Matrix<double, 2, 3> dr_dp;
  PinholeResidual(camera.p, left_px_, k_, residuals, jacobians ? &dr_dp : nullptr);
  if (!jacobians) return true;
  if (jacobians[0]) WriteJacobian<2, 4>(dr_dp * camera.dp_drotation, jacobians[0]);
  if (jacobians[1]) WriteJacobian<2, 3>(dr_dp, jacobians[1]);
  if (jacobians[2]) WriteJacobian<2, 3>(dr_dp * camera.dp_dpoint, jacobians[2]);
  return true;
}

bool MonoReprojectionCost::operator()(const double* rotation, const double* translation,
                                      const double* point, double* residuals) const {
  const double* parameters[] = {rotation, translation, point};
  return Evaluate(parameters, residuals, nullptr);
}

}  // namespace visloc::mapping
