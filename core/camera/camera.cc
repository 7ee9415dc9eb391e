#include "core/camera/camera.h"

#include <cmath>
#include <cstring>
#include <limits>

#include <Eigen/LU>

#include "core/util/check.h"
#include "core/util/cpu_dispatch.h"
#include "core/util/strings.h"

namespace visloc {

const char* LensModelName(LensModel model) {
  return model == LensModel::kEquidistant ? "equidistant" : "radial-tangential";
}

LensModel ParseLensModel(const std::string& name) {
  if (name == "radial-tangential" || name == "radtan") return LensModel::kRadialTangential;
  if (name == "equidistant") return LensModel::kEquidistant;
  throw InputError(StrCat("unknown lens model '", name,
                          "' (expected radial-tangential or equidistant)"));
}

std::array<const char*, 4> LensCoefficientNames(LensModel model) {
  if (model == LensModel::kEquidistant) return {"k1", "k2", "k3", "k4"};
  return {"k1", "k2", "p1", "p2"};
}

Lens Lens::Equidistant(double k1, double k2, double k3, double k4) {
  Lens lens;
  lens.model = LensModel::kEquidistant;
  lens.coefficients = {k1, k2, k3, k4};
  return lens;
}

bool Lens::IsIdeal() const {
  return model == LensModel::kRadialTangential && coefficients == std::array<double, 4>{};
}

bool Lens::operator==(const Lens& other) const {
  return model == other.model && coefficients == other.coefficients;
}

Camera::Camera(int width, int height, double fx, double fy, double cx, double cy, const Lens& lens)
    : width_(width), height_(height), fx_(fx), fy_(fy), cx_(cx), cy_(cy), lens_(lens) {
  VISLOC_CHECK(width > 0 && height > 0, "image size ", width, "x", height);
  VISLOC_CHECK(fx > 0 && fy > 0 && std::isfinite(fx) && std::isfinite(fy), "focal length ", fx,
               ", ", fy);
  VISLOC_CHECK(std::isfinite(cx) && std::isfinite(cy), "principal point ", cx, ", ", cy);
  for (double k : lens.coefficients) VISLOC_CHECK(std::isfinite(k), "lens coefficient ", k);
}

Camera Camera::FromHorizontalFov(int width, int height, double horizontal_fov_deg) {
  VISLOC_CHECK(horizontal_fov_deg > 0 && horizontal_fov_deg < 180, "fov ", horizontal_fov_deg);
  const double f = 0.5 * width / std::tan(0.5 * horizontal_fov_deg * M_PI / 180.0);
  return Camera(width, height, f, f, 0.5 * (width - 1), 0.5 * (height - 1));
}

Camera Camera::FisheyeFromDiagonalFov(int width, int height, double diagonal_fov_deg) {
  VISLOC_CHECK(diagonal_fov_deg > 0 && diagonal_fov_deg < 180, "fov ", diagonal_fov_deg);
  const double half_diagonal_px = 0.5 * std::hypot(width, height);
  const double f = half_diagonal_px / (0.5 * diagonal_fov_deg * M_PI / 180.0);
  return Camera(width, height, f, f, 0.5 * (width - 1), 0.5 * (height - 1),
                Lens::Equidistant(0, 0, 0, 0));
}

Eigen::Matrix3d Camera::K() const {
  Eigen::Matrix3d k;
  k << fx_, 0, cx_, 0, fy_, cy_, 0, 0, 1;
  return k;
}

std::array<double, 8> Camera::Params() const {
  const auto& k = lens_.coefficients;
  return {fx_, fy_, cx_, cy_, k[0], k[1], k[2], k[3]};
}

bool Camera::Project(const Eigen::Vector3d& point_in_cam, Eigen::Vector2d* pixel) const {
  if (point_in_cam.z() <= 1e-9) return false;
  const Eigen::Vector2d distorted = Distort(point_in_cam.head<2>() / point_in_cam.z());
  *pixel = Eigen::Vector2d(fx_ * distorted.x() + cx_, fy_ * distorted.y() + cy_);
  return true;
}

Eigen::Vector3d Camera::Unproject(const Eigen::Vector2d& pixel) const {
  const Eigen::Vector2d distorted((pixel.x() - cx_) / fx_, (pixel.y() - cy_) / fy_);
  const Eigen::Vector2d normalized = Undistort(distorted);
  return Eigen::Vector3d(normalized.x(), normalized.y(), 1.0);
}

namespace {

// Kannala-Brandt: theta_d(theta) and its derivative.
double ThetaDistorted(const std::array<double, 4>& k, double theta) {
  const double t2 = theta * theta;
  return theta * (1.0 + t2 * (k[0] + t2 * (k[1] + t2 * (k[2] + t2 * k[3]))));
}

double ThetaDistortedDerivative(const std::array<double, 4>& k, double theta) {
  const double t2 = theta * theta;
  return 1.0 + t2 * (3.0 * k[0] + t2 * (5.0 * k[1] + t2 * (7.0 * k[2] + t2 * 9.0 * k[3])));
}

// The radial-tangential (Brown-Conrady) distortion of normalized (x, y) and its Jacobian
// [j00 j01; j01 j11] (symmetric), for T = double or a vector of doubles: one formula serves the
// scalar Distort, DistortJacobian and Undistort and the batched undistortion, which therefore
// compute the same bits. k = (k1, k2, p1, p2).
template <typename T>
void DistortRadialTangential(const std::array<double, 4>& k, const T& x, const T& y, T* x_d,
                             T* y_d) {
  const auto& [k1, k2, p1, p2] = k;
  const T r2 = x * x + y * y;
  const T radial = 1.0 + k1 * r2 + k2 * r2 * r2;
  *x_d = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
  *y_d = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
}

template <typename T>
void DistortRadialTangentialJacobian(const std::array<double, 4>& k, const T& x, const T& y,
                                     T* j00, T* j01, T* j11) {
  const auto& [k1, k2, p1, p2] = k;
  const T r2 = x * x + y * y;
  const T radial = 1.0 + k1 * r2 + k2 * r2 * r2;
  const T d_radial_d_r2 = k1 + 2.0 * k2 * r2;
  *j00 = radial + 2.0 * x * x * d_radial_d_r2 + 2.0 * p1 * y + 6.0 * p2 * x;
  *j01 = 2.0 * x * y * d_radial_d_r2 + 2.0 * p1 * x + 2.0 * p2 * y;
  *j11 = radial + 2.0 * y * y * d_radial_d_r2 + 6.0 * p1 * y + 2.0 * p2 * x;
}

// One Newton step of undistortion at estimate (x, y) for the distorted point (x_d, y_d):
// (step_x, step_y) = J^-1 (Distort(x, y) - (x_d, y_d)), the 2x2 inverse in closed form.
template <typename T>
void UndistortStep(const std::array<double, 4>& k, const T& x, const T& y, const T& x_d,
                   const T& y_d, T* step_x, T* step_y) {
  T j00, j01, j11, distorted_x, distorted_y;
  DistortRadialTangentialJacobian(k, x, y, &j00, &j01, &j11);
  DistortRadialTangential(k, x, y, &distorted_x, &distorted_y);
  const T residual_x = distorted_x - x_d;
  const T residual_y = distorted_y - y_d;
  const T det = j00 * j11 - j01 * j01;
  *step_x = (j11 * residual_x - j01 * residual_y) / det;
  *step_y = (-j01 * residual_x + j00 * residual_y) / det;
}

}  // namespace

Eigen::Vector2d Camera::Distort(const Eigen::Vector2d& normalized) const {
  const auto& k = lens_.coefficients;
  if (lens_.model == LensModel::kEquidistant) {
    const double r = std::sqrt(normalized.x() * normalized.x() + normalized.y() * normalized.y());
    if (r < 1e-12) return normalized;
    return normalized * (ThetaDistorted(k, std::atan(r)) / r);
  }
  if (lens_.IsIdeal()) return normalized;
  Eigen::Vector2d distorted;
  DistortRadialTangential(k, normalized.x(), normalized.y(), &distorted.x(), &distorted.y());
  return distorted;
}

Eigen::Matrix2d Camera::DistortJacobian(const Eigen::Vector2d& normalized) const {
  const auto& k = lens_.coefficients;
  Eigen::Matrix2d jacobian;
  if (lens_.model == LensModel::kEquidistant) {
    // (x, y) -> g(r) (x, y) with g = theta_d(atan r) / r:
    // J = g I + g'(r) / r (x, y)(x, y)^T.
    const double r2 = normalized.x() * normalized.x() + normalized.y() * normalized.y();
    const double r = std::sqrt(r2);
    if (r < 1e-9) return Eigen::Matrix2d::Identity();
    const double theta = std::atan(r);
    const double g = ThetaDistorted(k, theta) / r;
    const double dg_dr = (ThetaDistortedDerivative(k, theta) / (1.0 + r2) - g) / r;
    jacobian = g * Eigen::Matrix2d::Identity() + (dg_dr / r) * normalized * normalized.transpose();
    return jacobian;
  }
  DistortRadialTangentialJacobian(k, normalized.x(), normalized.y(), &jacobian(0, 0),
                                  &jacobian(0, 1), &jacobian(1, 1));
  jacobian(1, 0) = jacobian(0, 1);
  return jacobian;
}

Eigen::Vector2d Camera::Undistort(const Eigen::Vector2d& distorted_normalized) const {
  if (lens_.model == LensModel::kEquidistant) {
    // Solve theta_d(theta) = |distorted| for theta in [0, pi/2), then r = tan(theta).
    const auto& k = lens_.coefficients;
    const double theta_d = distorted_normalized.norm();
    if (theta_d < 1e-12) return distorted_normalized;
    double theta = std::min(theta_d, 1.5);
    for (int iteration = 0; iteration < 20; ++iteration) {
      const double step =
          (ThetaDistorted(k, theta) - theta_d) / ThetaDistortedDerivative(k, theta);
      theta -= step;
      if (std::abs(step) < 1e-14) break;
    }
    if (!(theta >= 0.0 && theta < 0.5 * M_PI - 1e-6)) {
      return Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN());
    }
    return distorted_normalized * (std::tan(theta) / theta_d);
  }
  if (lens_.IsIdeal()) return distorted_normalized;
  Eigen::Vector2d estimate = distorted_normalized;
  for (int iteration = 0; iteration < 20; ++iteration) {
    Eigen::Vector2d step;
    UndistortStep(lens_.coefficients, estimate.x(), estimate.y(), distorted_normalized.x(),
                  distorted_normalized.y(), &step.x(), &step.y());
    estimate -= step;
    if (step.squaredNorm() < 1e-28) break;
  }
  return estimate;
}

double Camera::PixelScale(const Eigen::Vector2d& normalized) const {
  if (lens_.IsIdeal()) return 1.0;
  return std::sqrt(std::abs(DistortJacobian(normalized).determinant()));
}

namespace {

// Camera::Undistort and Camera::PixelScale of a radial-tangential lens with coefficients k, for
// eight distorted normalized points (x_d[l], y_d[l]): the lanes go through Undistort's own
// templates, so every lane computes what the scalar code does; a lane stops updating at the
// iteration where the scalar loop breaks. The scales' square roots are taken by the caller.
VISLOC_SIMD_CLONES void UndistortRadialTangential8(const std::array<double, 4>& k,
                                                   const double* x_d, const double* y_d,
                                                   double* x_out, double* y_out,
                                                   double* abs_det_out) {
  Doubles8 dx, dy;
  std::memcpy(&dx, x_d, sizeof dx);
  std::memcpy(&dy, y_d, sizeof dy);
  Doubles8 x = dx, y = dy;
  Int64s8 active = {-1, -1, -1, -1, -1, -1, -1, -1};
  for (int iteration = 0; iteration < 20; ++iteration) {
    Doubles8 step_x, step_y;
    UndistortStep(k, x, y, dx, dy, &step_x, &step_y);
    x = active ? x - step_x : x;
    y = active ? y - step_y : y;
    active = active && !(step_x * step_x + step_y * step_y < 1e-28);
    bool any = false;
    for (int l = 0; l < 8; ++l) any = any || active[l] != 0;
    if (!any) break;
  }
  Doubles8 j00, j01, j11;
  DistortRadialTangentialJacobian(k, x, y, &j00, &j01, &j11);
  const Doubles8 det = j00 * j11 - j01 * j01;
  std::memcpy(x_out, &x, sizeof x);
  std::memcpy(y_out, &y, sizeof y);
  for (int l = 0; l < 8; ++l) abs_det_out[l] = std::abs(det[l]);
}

}  // namespace

void Camera::UnprojectMany(const std::vector<Eigen::Vector2f>& pixels,
                           std::vector<Eigen::Vector2d>* normalized,
                           std::vector<double>* pixel_scales) const {
  const size_t n = pixels.size();
  normalized->resize(n);
  pixel_scales->resize(n);
  const bool batched = lens_.model == LensModel::kRadialTangential && !lens_.IsIdeal();
  size_t i = 0;
  for (; batched && i + 8 <= n; i += 8) {
    double x_d[8], y_d[8], x[8], y[8], abs_det[8];
    for (int l = 0; l < 8; ++l) {
      const Eigen::Vector2d pixel = pixels[i + l].cast<double>();
      x_d[l] = (pixel.x() - cx_) / fx_;  // As Unproject.
      y_d[l] = (pixel.y() - cy_) / fy_;
    }
    UndistortRadialTangential8(lens_.coefficients, x_d, y_d, x, y, abs_det);
    for (int l = 0; l < 8; ++l) {
      (*normalized)[i + l] = Eigen::Vector2d(x[l], y[l]);
      (*pixel_scales)[i + l] = std::sqrt(abs_det[l]);
    }
  }
  for (; i < n; ++i) {
    (*normalized)[i] = Unproject(pixels[i].cast<double>()).head<2>();
    (*pixel_scales)[i] = PixelScale((*normalized)[i]);
  }
}

bool Camera::IsInImage(const Eigen::Vector2d& pixel, double margin_px) const {
  return pixel.x() >= -0.5 + margin_px && pixel.y() >= -0.5 + margin_px &&
         pixel.x() <= width_ - 0.5 - margin_px && pixel.y() <= height_ - 0.5 - margin_px;
}

Camera Camera::Scaled(double factor) const {
  VISLOC_CHECK(factor > 0, "scale factor ", factor);
  // Pixel centres: the continuous coordinate u + 0.5 scales, so cx' = (cx + 0.5) f - 0.5.
  return Camera(static_cast<int>(std::lround(width_ * factor)),
                static_cast<int>(std::lround(height_ * factor)), fx_ * factor, fy_ * factor,
                (cx_ + 0.5) * factor - 0.5, (cy_ + 0.5) * factor - 0.5, lens_);
}

std::string ToString(const Camera& camera) {
  const auto& k = camera.lens().coefficients;
  const auto names = LensCoefficientNames(camera.lens().model);
  std::string text = StrCat(camera.width(), "x", camera.height(), " fx ",
                            FormatFixed(camera.fx(), 2), " fy ", FormatFixed(camera.fy(), 2),
                            " cx ", FormatFixed(camera.cx(), 2), " cy ",
                            FormatFixed(camera.cy(), 2), ", ", LensModelName(camera.lens().model));
  for (int i = 0; i < 4; ++i) text += StrCat(" ", names[i], " ", FormatFixed(k[i], 5));
  return text;
}

}  // namespace visloc
