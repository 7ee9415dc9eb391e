#include "core/camera/stereo_rectifier.h"

#include <cmath>
#include <limits>

#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>
#include <opencv2/imgproc.hpp>

#include "core/camera/opencv_camera.h"
#include "core/util/check.h"
#include "core/util/strings.h"

namespace visloc {
namespace {

bool IsFisheye(const Camera& camera) { return camera.lens().model == LensModel::kEquidistant; }

void UndistortRectifyMap(const Camera& camera, const cv::Mat& rect_from_raw,
                         const cv::Mat& projection, const cv::Size& size, cv::Mat* map_x,
                         cv::Mat* map_y) {
  if (IsFisheye(camera)) {
    cv::fisheye::initUndistortRectifyMap(CameraMatrix(camera), LensCoefficients(camera),
                                         rect_from_raw, projection, size, CV_32FC1, *map_x,
                                         *map_y);
  } else {
    cv::initUndistortRectifyMap(CameraMatrix(camera), LensCoefficients(camera),
                                rect_from_raw, projection, size, CV_32FC1, *map_x, *map_y);
  }
}

Eigen::Quaterniond ToQuaternion(const cv::Mat& rotation) {
  Eigen::Matrix3d r;
  cv::cv2eigen(rotation, r);
  return Eigen::Quaterniond(r).normalized();
}

}  // namespace

StereoRectifier::StereoRectifier(const Camera& left, const Camera& right,
                                 const Rigid3d& right_from_left)
    : left_(left), right_(right) {
  VISLOC_CHECK(left.width() == right.width() && left.height() == right.height(),
               "stereo cameras differ in size: ", left.width(), "x", left.height(), " vs ",
               right.width(), "x", right.height());
  VISLOC_CHECK(right_from_left.translation.norm() > 1e-6, "stereo baseline is zero");
  // The rectified pair puts the right camera at +x of the left one (d = u_left - u_right > 0).
  const Eigen::Vector3d right_in_left = right_from_left.Inverse().translation;
  if (std::abs(right_in_left.y()) > std::abs(right_in_left.x())) {
    throw InputError(StrCat("the right camera sits ", FormatFixed(right_in_left.y(), 3),
                            " m below the left one: vertical stereo rigs are not supported"));
  }
  if (right_in_left.x() <= 0) {
    throw InputError(StrCat("the right camera sits ", FormatFixed(-right_in_left.x(), 3),
                            " m to the left of the left one: are the two cameras swapped?"));
  }
  cv::Mat rotation, translation;
  cv::eigen2cv(Eigen::Matrix3d(right_from_left.rotation.toRotationMatrix()), rotation);
  cv::eigen2cv(Eigen::Vector3d(right_from_left.translation), translation);
  const cv::Size size(left.width(), left.height());
  cv::Mat r1, r2, p1, p2, q;
  if (IsFisheye(left) != IsFisheye(right)) {
    throw InputError("a stereo pair of a fisheye and an ordinary lens is not supported");
  }
  if (IsFisheye(left)) {
    // A pinhole view of the fisheyes' common field: balance 0 keeps only valid pixels, and the
    // rays too far off axis for a pinhole are left to the canvas below (or dropped).
    cv::fisheye::stereoRectify(CameraMatrix(left), LensCoefficients(left),
                               CameraMatrix(right), LensCoefficients(right), size, rotation,
                               translation, r1, r2, p1, p2, q, cv::CALIB_ZERO_DISPARITY, size,
                               /*balance=*/0.0, /*fov_scale=*/1.0);
  } else {
    // alpha = 0 crops to valid pixels only, so no black borders produce spurious features.
    cv::stereoRectify(CameraMatrix(left), LensCoefficients(left), CameraMatrix(right),
                      LensCoefficients(right), size, rotation, translation, r1, r2, p1, p2,
                      q, cv::CALIB_ZERO_DISPARITY, /*alpha=*/0.0, size);
  }
  const double f = p1.at<double>(0, 0);
  rectified_camera_ = Camera(left.width(), left.height(), f, p1.at<double>(1, 1),
                                    p1.at<double>(0, 2), p1.at<double>(1, 2));
  // P2(0, 3) = -f * B for a right camera displaced along +x in the rectified frame.
  baseline_m_ = std::abs(p2.at<double>(0, 3) / f);
  rect_from_left_ = ToQuaternion(r1);
  rect_from_right_ = ToQuaternion(r2);
  // The canvas: the rectified bounding box of both raw images' borders, at most half an image
  // beyond the valid region on each side.
  Eigen::Vector2d low(0, 0), high(left.width() - 1, left.height() - 1);
  for (const bool is_left : {true, false}) {
    const int w = left.width(), h = left.height();
    for (int t = 0; t <= 64; ++t) {
      const double x = (w - 1) * t / 64.0, y = (h - 1) * t / 64.0;
      for (const Eigen::Vector2d& raw : {Eigen::Vector2d(x, 0), Eigen::Vector2d(x, h - 1),
                                         Eigen::Vector2d(0, y), Eigen::Vector2d(w - 1, y)}) {
        const Eigen::Vector2d rect = is_left ? RectifyLeftPixel(raw) : RectifyRightPixel(raw);
        if (!rect.allFinite()) continue;  // A fisheye's rim, beyond 90 degrees.
        low = low.cwiseMin(rect);
        high = high.cwiseMax(rect);
      }
    }
  }
  const Eigen::Vector2d limit(left.width() / 2.0, left.height() / 2.0);
  canvas_offset_px_ = (-low).cwiseMin(limit).array().ceil().matrix();
  const Eigen::Vector2d beyond =
      (high - Eigen::Vector2d(left.width() - 1, left.height() - 1)).cwiseMin(limit);
  canvas_size_ = cv::Size(left.width() + static_cast<int>(canvas_offset_px_.x()) +
                              static_cast<int>(std::ceil(beyond.x())),
                          left.height() + static_cast<int>(canvas_offset_px_.y()) +
                              static_cast<int>(std::ceil(beyond.y())));
  for (cv::Mat* p : {&p1, &p2}) {
    p->at<double>(0, 2) += canvas_offset_px_.x();
    p->at<double>(1, 2) += canvas_offset_px_.y();
  }
  UndistortRectifyMap(left, r1, p1, canvas_size_, &left_map_x_, &left_map_y_);
  UndistortRectifyMap(right, r2, p2, canvas_size_, &right_map_x_, &right_map_y_);
}

void StereoRectifier::Rectify(const cv::Mat& left_raw, const cv::Mat& right_raw, cv::Mat* left_rect,
                              cv::Mat* right_rect) const {
  const cv::Size expected(left_.width(), left_.height());
  VISLOC_CHECK(left_raw.size() == expected && right_raw.size() == expected,
               "stereo images must be ", expected.width, "x", expected.height);
  cv::remap(left_raw, *left_rect, left_map_x_, left_map_y_, cv::INTER_LINEAR);
  cv::remap(right_raw, *right_rect, right_map_x_, right_map_y_, cv::INTER_LINEAR);
}

namespace {
Eigen::Vector2d RectifyPixel(const Camera& raw, const Eigen::Quaterniond& rect_from_raw,
                             const Camera& rectified, const Eigen::Vector2d& pixel) {
  const Eigen::Vector3d ray_in_rect = rect_from_raw * raw.Unproject(pixel);
  Eigen::Vector2d rect_pixel = Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN());
  if (ray_in_rect.allFinite()) rectified.Project(ray_in_rect, &rect_pixel);
  return rect_pixel;
}
}  // namespace

Eigen::Vector2d StereoRectifier::RectifyLeftPixel(const Eigen::Vector2d& raw_pixel) const {
  return RectifyPixel(left_, rect_from_left_, rectified_camera_, raw_pixel);
}

Eigen::Vector2d StereoRectifier::RectifyRightPixel(const Eigen::Vector2d& raw_pixel) const {
  // The right rectified camera has the same intrinsics; its x offset is in P2 and applies to
  // projections of 3D points, not to rays, so projecting the rotated ray is correct.
  return RectifyPixel(right_, rect_from_right_, rectified_camera_, raw_pixel);
}

}  // namespace visloc
