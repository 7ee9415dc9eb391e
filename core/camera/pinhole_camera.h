#pragma once
// Pinhole camera with radial-tangential ("radtan", OpenCV plumb-bob without k3) distortion.
//
// Frames and units: points are in the camera frame (OpenCV: x right, y down, z forward),
// metres. Pixel coordinates have their origin at the centre of the top-left pixel, so pixel
// (0, 0) covers [-0.5, 0.5] x [-0.5, 0.5] (OpenCV's convention). Normalized coordinates are
// (x/z, y/z) before distortion.
//
// Distortion of normalized (x, y), r^2 = x^2 + y^2:
//   x_d = x (1 + k1 r^2 + k2 r^4) + 2 p1 x y + p2 (r^2 + 2 x^2)
//   y_d = y (1 + k1 r^2 + k2 r^4) + p1 (r^2 + 2 y^2) + 2 p2 x y
// pixel = (fx x_d + cx, fy y_d + cy).

#include <array>

#include <Eigen/Core>

namespace visloc {

struct RadTanDistortion {
  double k1 = 0.0;
  double k2 = 0.0;
  double p1 = 0.0;
  double p2 = 0.0;
  bool IsZero() const { return k1 == 0.0 && k2 == 0.0 && p1 == 0.0 && p2 == 0.0; }
};

class PinholeCamera {
 public:
  PinholeCamera() = default;
  // Throws CheckError for non-positive sizes or focal lengths.
  PinholeCamera(int width, int height, double fx, double fy, double cx, double cy,
                const RadTanDistortion& distortion = {});
  // An undistorted camera of the given horizontal field of view with the principal point at
  // the image centre and square pixels.
  static PinholeCamera FromHorizontalFov(int width, int height, double horizontal_fov_deg);

  int width() const { return width_; }
  int height() const { return height_; }
  double fx() const { return fx_; }
  double fy() const { return fy_; }
  double cx() const { return cx_; }
  double cy() const { return cy_; }
  const RadTanDistortion& distortion() const { return distortion_; }
  Eigen::Matrix3d K() const;
  // {fx, fy, cx, cy, k1, k2, p1, p2}
  std::array<double, 8> Params() const;

  // Projects a camera-frame point to pixels. Returns false (pixel untouched) when the point is
  // not in front of the camera (z <= 1e-9 m). The pixel may lie outside the image.
  bool Project(const Eigen::Vector3d& point_in_cam, Eigen::Vector2d* pixel) const;
  // The viewing ray of a pixel as (x, y, 1): the point at depth z is z * ray.
  Eigen::Vector3d Unproject(const Eigen::Vector2d& pixel) const;

  Eigen::Vector2d Distort(const Eigen::Vector2d& normalized) const;
  // Inverts Distort by Newton iteration; accurate to ~1e-12 within the image for realistic
  // lens models (fixed-point iteration, as in cv::undistortPoints, is not).
  Eigen::Vector2d Undistort(const Eigen::Vector2d& distorted_normalized) const;

  bool IsInImage(const Eigen::Vector2d& pixel, double margin_px = 0.0) const;
  // The same camera for an image scaled by `factor` (e.g. 0.5 for half resolution).
  PinholeCamera Scaled(double factor) const;

 private:
  int width_ = 0;
  int height_ = 0;
  double fx_ = 1.0;
  double fy_ = 1.0;
  double cx_ = 0.0;
  double cy_ = 0.0;
  RadTanDistortion distortion_;
};

}  // namespace visloc
