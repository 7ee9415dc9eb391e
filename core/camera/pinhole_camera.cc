#include "core/camera/pinhole_camera.h"

#include <cmath>

#include <Eigen/LU>

#include "core/util/check.h"

namespace visloc {

PinholeCamera::PinholeCamera(int width, int height, double fx, double fy, double cx, double cy,
                             const RadTanDistortion& distortion)
    : width_(width), height_(height), fx_(fx), fy_(fy), cx_(cx), cy_(cy), distortion_(distortion) {
  VISLOC_CHECK(width > 0 && height > 0, "image size ", width, "x", height);
  VISLOC_CHECK(fx > 0 && fy > 0 && std::isfinite(fx) && std::isfinite(fy), "focal length ", fx,
               ", ", fy);
  VISLOC_CHECK(std::isfinite(cx) && std::isfinite(cy), "principal point ", cx, ", ", cy);
}

PinholeCamera PinholeCamera::FromHorizontalFov(int width, int height, double horizontal_fov_deg) {
  VISLOC_CHECK(horizontal_fov_deg > 0 && horizontal_fov_deg < 180, "fov ", horizontal_fov_deg);
  const double f = 0.5 * width / std::tan(0.5 * horizontal_fov_deg * M_PI / 180.0);
  return PinholeCamera(width, height, f, f, 0.5 * (width - 1), 0.5 * (height - 1));
}

Eigen::Matrix3d PinholeCamera::K() const {
  Eigen::Matrix3d k;
  k << fx_, 0, cx_, 0, fy_, cy_, 0, 0, 1;
  return k;
}

std::array<double, 8> PinholeCamera::Params() const {
  return {fx_, fy_, cx_, cy_, distortion_.k1, distortion_.k2, distortion_.p1, distortion_.p2};
}

bool PinholeCamera::Project(const Eigen::Vector3d& point_in_cam, Eigen::Vector2d* pixel) const {
  if (point_in_cam.z() <= 1e-9) return false;
  const Eigen::Vector2d distorted = Distort(point_in_cam.head<2>() / point_in_cam.z());
  *pixel = Eigen::Vector2d(fx_ * distorted.x() + cx_, fy_ * distorted.y() + cy_);
  return true;
}

Eigen::Vector3d PinholeCamera::Unproject(const Eigen::Vector2d& pixel) const {
  const Eigen::Vector2d distorted((pixel.x() - cx_) / fx_, (pixel.y() - cy_) / fy_);
  const Eigen::Vector2d normalized = Undistort(distorted);
  return Eigen::Vector3d(normalized.x(), normalized.y(), 1.0);
}

Eigen::Vector2d PinholeCamera::Distort(const Eigen::Vector2d& normalized) const {
  if (distortion_.IsZero()) return normalized;
  const auto& [k1, k2, p1, p2] = distortion_;
  const double x = normalized.x();
  const double y = normalized.y();
  const double r2 = x * x + y * y;
  const double radial = 1.0 + k1 * r2 + k2 * r2 * r2;
  return Eigen::Vector2d(x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
                         y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y);
}

Eigen::Vector2d PinholeCamera::Undistort(const Eigen::Vector2d& distorted_normalized) const {
  if (distortion_.IsZero()) return distorted_normalized;
  const auto& [k1, k2, p1, p2] = distortion_;
  Eigen::Vector2d estimate = distorted_normalized;
  for (int iteration = 0; iteration < 20; ++iteration) {
    const double x = estimate.x();
    const double y = estimate.y();
    const double r2 = x * x + y * y;
    const double radial = 1.0 + k1 * r2 + k2 * r2 * r2;
    const double d_radial_d_r2 = k1 + 2.0 * k2 * r2;
    // Jacobian of Distort with respect to (x, y).
    Eigen::Matrix2d jacobian;
    jacobian(0, 0) = radial + 2.0 * x * x * d_radial_d_r2 + 2.0 * p1 * y + 6.0 * p2 * x;
    jacobian(0, 1) = 2.0 * x * y * d_radial_d_r2 + 2.0 * p1 * x + 2.0 * p2 * y;
    jacobian(1, 0) = 2.0 * x * y * d_radial_d_r2 + 2.0 * p1 * x + 2.0 * p2 * y;
    jacobian(1, 1) = radial + 2.0 * y * y * d_radial_d_r2 + 6.0 * p1 * y + 2.0 * p2 * x;
    const Eigen::Vector2d residual = Distort(estimate) - distorted_normalized;
    const Eigen::Vector2d step = jacobian.partialPivLu().solve(residual);
    estimate -= step;
    if (step.squaredNorm() < 1e-28) break;
  }
  return estimate;
}

bool PinholeCamera::IsInImage(const Eigen::Vector2d& pixel, double margin_px) const {
  return pixel.x() >= -0.5 + margin_px && pixel.y() >= -0.5 + margin_px &&
         pixel.x() <= width_ - 0.5 - margin_px && pixel.y() <= height_ - 0.5 - margin_px;
}

PinholeCamera PinholeCamera::Scaled(double factor) const {
  VISLOC_CHECK(factor > 0, "scale factor ", factor);
  // Pixel centres: the continuous coordinate u + 0.5 scales, so cx' = (cx + 0.5) f - 0.5.
  return PinholeCamera(static_cast<int>(std::lround(width_ * factor)),
                       static_cast<int>(std::lround(height_ * factor)), fx_ * factor, fy_ * factor,
                       (cx_ + 0.5) * factor - 0.5, (cy_ + 0.5) * factor - 0.5, distortion_);
}

}  // namespace visloc
