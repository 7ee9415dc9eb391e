#pragma once
// A central camera with one of two lens models, OpenCV's and EuRoC's / Kalibr's conventions:
//
//   radial-tangential  ("pinhole" + "radial-tangential": OpenCV's plumb bob without k3), for
//                      ordinary lenses. Of normalized (x, y), r^2 = x^2 + y^2:
//                        x_d = x (1 + k1 r^2 + k2 r^4) + 2 p1 x y + p2 (r^2 + 2 x^2)
//                        y_d = y (1 + k1 r^2 + k2 r^4) + p1 (r^2 + 2 y^2) + 2 p2 x y
//   equidistant        (Kannala-Brandt, OpenCV's cv::fisheye), for fisheye lenses. The angle
//                      theta of the ray from the optical axis, r = |(x, y)| = tan(theta):
//                        theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8)
//                        (x_d, y_d) = theta_d / r (x, y)
//   pixel = (fx x_d + cx, fy y_d + cy).
//
// Frames and units: points are in the camera frame (OpenCV: x right, y down, z forward),
// metres. Pixel coordinates have their origin at the centre of the top-left pixel, so pixel
// (0, 0) covers [-0.5, 0.5] x [-0.5, 0.5] (OpenCV's convention). Normalized coordinates are
// (x/z, y/z) before distortion: rays up to 90 degrees from the optical axis (fields of view
// below 180 degrees), which every solver downstream works with.

#include <array>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace visloc {

enum class LensModel { kRadialTangential, kEquidistant };
// "radial-tangential" or "equidistant" (EuRoC's distortion_model values).
const char* LensModelName(LensModel model);
// Also accepts "radtan"; throws InputError otherwise.
LensModel ParseLensModel(const std::string& name);
// The names of a model's four coefficients: k1 k2 p1 p2, or k1 k2 k3 k4.
std::array<const char*, 4> LensCoefficientNames(LensModel model);

struct Lens {
  LensModel model = LensModel::kRadialTangential;
  // radial-tangential: k1 k2 p1 p2; equidistant: k1 k2 k3 k4.
  std::array<double, 4> coefficients{};

  Lens() = default;
  // Radial-tangential coefficients.
  Lens(double k1, double k2, double p1, double p2)
      : model(LensModel::kRadialTangential), coefficients{k1, k2, p1, p2} {}
  static Lens Equidistant(double k1, double k2, double k3, double k4);
  // A perfect pinhole: radial-tangential with no distortion.
  bool IsIdeal() const;
  bool operator==(const Lens& other) const;
};

class Camera {
 public:
  Camera() = default;
  // Throws CheckError for non-positive sizes or focal lengths.
  Camera(int width, int height, double fx, double fy, double cx, double cy, const Lens& lens = {});
  // A perfect pinhole of the given horizontal field of view with the principal point at the
  // image centre and square pixels.
  static Camera FromHorizontalFov(int width, int height, double horizontal_fov_deg);
  // An equidistant fisheye (k1..k4 = 0) whose image diagonal spans `diagonal_fov_deg` (below
  // 180), principal point at the centre, square pixels.
  static Camera FisheyeFromDiagonalFov(int width, int height, double diagonal_fov_deg);

  int width() const { return width_; }
  int height() const { return height_; }
  double fx() const { return fx_; }
  double fy() const { return fy_; }
  double cx() const { return cx_; }
  double cy() const { return cy_; }
  const Lens& lens() const { return lens_; }
  Eigen::Matrix3d K() const;
  // {fx, fy, cx, cy, the lens's four coefficients}
  std::array<double, 8> Params() const;

  // Projects a camera-frame point to pixels. Returns false (pixel untouched) when the point is
  // not in front of the camera (z <= 1e-9 m). The pixel may lie outside the image.
  bool Project(const Eigen::Vector3d& point_in_cam, Eigen::Vector2d* pixel) const;
  // The viewing ray of a pixel as (x, y, 1): the point at depth z is z * ray. NaN for a pixel
  // 90 degrees or more off the optical axis (a fisheye's corners may be).
  Eigen::Vector3d Unproject(const Eigen::Vector2d& pixel) const;

  Eigen::Vector2d Distort(const Eigen::Vector2d& normalized) const;
  // Inverts Distort by Newton iteration; accurate to ~1e-12 within the image for realistic
  // lens models (fixed-point iteration, as in cv::undistortPoints, is not).
  Eigen::Vector2d Undistort(const Eigen::Vector2d& distorted_normalized) const;
  // How many pixels a unit of normalized coordinates spans at `normalized`, relative to the
  // focal length (sqrt(fx fy)): the square root of the area scale of the lens mapping there.
  // 1 for a perfect pinhole; below 1 towards a fisheye's rim, where pixels cover more angle.
  // Solvers that measure errors in normalized units weigh them by it, so that a pixel means a
  // pixel everywhere in the image.
  double PixelScale(const Eigen::Vector2d& normalized) const;
  // Unproject's (x, y) and their PixelScale for many pixels, the same bits as one at a time
  // (a query's keypoints). Radial-tangential lenses undistort eight pixels at a time: each lane
  // runs Undistort's Newton iterations, in the same operations, and stops where it would.
  void UnprojectMany(const std::vector<Eigen::Vector2f>& pixels,
                     std::vector<Eigen::Vector2d>* normalized,
                     std::vector<double>* pixel_scales) const;

  bool IsInImage(const Eigen::Vector2d& pixel, double margin_px = 0.0) const;
  // The same camera for an image scaled by `factor` (e.g. 0.5 for half resolution).
  Camera Scaled(double factor) const;

 private:
  // Jacobian of Distort at `normalized`.
  Eigen::Matrix2d DistortJacobian(const Eigen::Vector2d& normalized) const;

  int width_ = 0;
  int height_ = 0;
  double fx_ = 1.0;
  double fy_ = 1.0;
  double cx_ = 0.0;
  double cy_ = 0.0;
  Lens lens_;
};

// "752x480 fx 458.65 fy 457.30 cx 367.22 cy 248.38, radial-tangential k1 -0.2834 ..." for
// reports.
std::string ToString(const Camera& camera);

}  // namespace visloc
