#include "core/calibration/calibration.h"

#include <algorithm>
#include <cmath>

#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>
#include <opencv2/imgproc.hpp>

#include "core/camera/opencv_camera.h"
#include "core/util/check.h"
#include "core/util/strings.h"

namespace visloc {

void ChessboardSpec::Check() const {
  VISLOC_CHECK(cols >= 3 && rows >= 3 && cols != rows, "board ", cols, "x", rows,
               " (inner corners; at least 3 each, and different, so its orientation is known)");
  VISLOC_CHECK(square_m > 0 && std::isfinite(square_m), "square ", square_m, " m");
}

void CalibrationOptions::Check() const {
  board.Check();
  VISLOC_CHECK(min_views >= 3 && min_coverage >= 0 && min_coverage <= 1 && max_rms_px > 0,
               "calibration warning thresholds");
}

namespace {

constexpr int kGridCols = 8, kGridRows = 6;  // For the coverage.

// The board's 180-degree symmetry leaves the detector free to start at either end. Views of a
// pair see the board from nearly the same place, so the right view's order is the one whose
// corners lie on the left view's rows (a horizontal rig), the same point of the board first.
void OrderLike(const std::vector<cv::Point2f>& left, std::vector<cv::Point2f>* right) {
  double same = 0, reversed = 0;
  const size_t n = left.size();
  for (size_t i = 0; i < n; ++i) {
    same += std::abs(left[i].y - (*right)[i].y);
    reversed += std::abs(left[i].y - (*right)[n - 1 - i].y);
  }
  if (reversed < same) std::reverse(right->begin(), right->end());
}

}  // namespace

std::vector<cv::Point2f> FindChessboard(const cv::Mat& grey, const ChessboardSpec& board) {
  VISLOC_CHECK(grey.type() == CV_8UC1 && !grey.empty(), "chessboards need 8-bit grey images");
  const cv::Size pattern(board.cols, board.rows);
  std::vector<cv::Point2f> corners;
  if (cv::findChessboardCorners(grey, pattern, corners,
                                cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE)) {
    // A refinement window well inside one square: the closest two neighbouring corners.
    double spacing = 1e9;
    for (int r = 0; r < board.rows; ++r) {
      for (int c = 0; c + 1 < board.cols; ++c) {
        spacing = std::min(spacing, cv::norm(corners[r * board.cols + c + 1] -
                                             corners[r * board.cols + c]));
      }
    }
    const int half = std::clamp(static_cast<int>(0.4 * spacing), 2, 5);
    cv::cornerSubPix(grey, corners, cv::Size(half, half), cv::Size(-1, -1),
                     cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 40, 0.001));
  } else if (!cv::findChessboardCornersSB(
                 grey, pattern, corners,
                 cv::CALIB_CB_NORMALIZE_IMAGE | cv::CALIB_CB_EXHAUSTIVE | cv::CALIB_CB_ACCURACY)) {
    // The sector-based detector takes strongly distorted (fisheye) and blurred views.
    return {};
  }
  return corners;
}

namespace {

struct Views {
  std::vector<std::vector<cv::Point3f>> object;
  std::vector<std::vector<cv::Point2f>> image;
};

std::vector<cv::Point3f> BoardPoints(const ChessboardSpec& board) {
  std::vector<cv::Point3f> points;
  for (int r = 0; r < board.rows; ++r) {
    for (int c = 0; c < board.cols; ++c) {
      points.emplace_back(static_cast<float>(c * board.square_m),
                          static_cast<float>(r * board.square_m), 0.0f);
    }
  }
  return points;
}

Rigid3d PoseFromRvecTvec(const cv::Mat& rvec, const cv::Mat& tvec) {
  cv::Mat rotation;
  cv::Rodrigues(rvec, rotation);
  Eigen::Matrix3d r;
  Eigen::Vector3d t;
  cv::cv2eigen(rotation, r);
  cv::cv2eigen(tvec.reshape(1, 3), t);
  return Rigid3d(Eigen::Quaterniond(r).normalized(), t);
}

template <typename T>
std::vector<std::vector<cv::Point_<T>>> Cast2(const std::vector<std::vector<cv::Point2f>>& in) {
  std::vector<std::vector<cv::Point_<T>>> out;
  for (const auto& view : in) out.emplace_back(view.begin(), view.end());
  return out;
}

template <typename T>
std::vector<std::vector<cv::Point3_<T>>> Cast3(const std::vector<std::vector<cv::Point3f>>& in) {
  std::vector<std::vector<cv::Point3_<T>>> out;
  for (const auto& view : in) out.emplace_back(view.begin(), view.end());
  return out;
}

// Intrinsics and lens by OpenCV, then the errors by visloc's camera model.
CameraCalibration CalibrateOne(const Views& views, const cv::Size& size, LensModel model) {
  cv::Mat k, d;
  std::vector<cv::Mat> rvecs, tvecs;
  try {
    if (model == LensModel::kEquidistant) {
      cv::fisheye::calibrate(Cast3<double>(views.object), Cast2<double>(views.image), size, k, d,
                             rvecs, tvecs,
                             cv::fisheye::CALIB_RECOMPUTE_EXTRINSIC | cv::fisheye::CALIB_FIX_SKEW,
                             cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 200,
                                              1e-12));
    } else {
      cv::calibrateCamera(views.object, views.image, size, k, d, rvecs, tvecs, cv::CALIB_FIX_K3);
    }
  } catch (const cv::Exception& e) {
    throw InputError(StrCat("calibration failed (", e.err, "): the views do not constrain the ",
                            LensModelName(model), " model; take more views, tilted and across "
                            "the whole image"));
  }
  d = d.reshape(1, 1);
  d.convertTo(d, CV_64F);
  const Lens lens = model == LensModel::kEquidistant
                        ? Lens::Equidistant(d.at<double>(0), d.at<double>(1), d.at<double>(2),
                                            d.at<double>(3))
                        : Lens(d.at<double>(0), d.at<double>(1), d.at<double>(2), d.at<double>(3));
  CameraCalibration result;
  result.camera = Camera(size.width, size.height, k.at<double>(0, 0), k.at<double>(1, 1),
                         k.at<double>(0, 2), k.at<double>(1, 2), lens);
  double total_sq = 0;
  size_t total = 0;
  std::vector<char> cells(kGridCols * kGridRows, 0);
  for (size_t v = 0; v < views.image.size(); ++v) {
    const Rigid3d cam_from_board = PoseFromRvecTvec(rvecs[v], tvecs[v]);
    double view_sq = 0;
    for (size_t i = 0; i < views.image[v].size(); ++i) {
      const cv::Point3f& o = views.object[v][i];
      const cv::Point2f& seen = views.image[v][i];
      Eigen::Vector2d pixel(1e9, 1e9);
      result.camera.Project(cam_from_board * Eigen::Vector3d(o.x, o.y, o.z), &pixel);
      const double e2 = (pixel - Eigen::Vector2d(seen.x, seen.y)).squaredNorm();
      view_sq += e2;
      const int cx = std::clamp(static_cast<int>(seen.x * kGridCols / size.width), 0, kGridCols - 1);
      const int cy = std::clamp(static_cast<int>(seen.y * kGridRows / size.height), 0, kGridRows - 1);
      cells[cy * kGridCols + cx] = 1;
    }
    result.view_rms_px.push_back(std::sqrt(view_sq / views.image[v].size()));
    total_sq += view_sq;
    total += views.image[v].size();
  }
  result.rms_px = std::sqrt(total_sq / std::max<size_t>(1, total));
  result.coverage = std::count(cells.begin(), cells.end(), 1) / static_cast<double>(cells.size());
  return result;
}

void Warn(const char* name, const CameraCalibration& c, const CalibrationOptions& options,
          std::vector<std::string>* warnings) {
  if (c.coverage < options.min_coverage) {
    warnings->push_back(StrCat("the board's corners reached ", std::lround(100 * c.coverage),
                               "% of the ", name, " image (cells of an 8x6 grid): hold it into ",
                               "the corners and along the edges too"));
  }
  if (c.rms_px > options.max_rms_px) {
    warnings->push_back(StrCat("the ", name, " camera's RMS reprojection error is ",
                               FormatFixed(c.rms_px, 2), " px (over ",
                               FormatFixed(options.max_rms_px, 1), "): blurred views, a bent ",
                               "board, or the wrong --board, --square or --model?"));
  }
}

}  // namespace

CalibrationResult Calibrate(const std::vector<cv::Mat>& left, const std::vector<cv::Mat>& right,
                            const CalibrationOptions& options) {
  options.Check();
  const bool stereo = !right.empty();
  if (left.empty()) throw InputError("no images");
  if (stereo && right.size() != left.size()) {
    throw InputError(StrCat(left.size(), " left images but ", right.size(), " right images: ",
                            "stereo calibration takes pairs"));
  }
  const cv::Size size = left.front().size();
  for (size_t i = 0; i < left.size(); ++i) {
    if (left[i].size() != size || (stereo && right[i].size() != size)) {
      throw InputError(StrCat("image ", i + 1, " is not ", size.width, "x", size.height,
                              " like the first"));
    }
  }
  CalibrationResult result;
  Views left_views, right_views;
  const std::vector<cv::Point3f> board = BoardPoints(options.board);
  for (size_t i = 0; i < left.size(); ++i) {
    std::vector<cv::Point2f> l = FindChessboard(left[i], options.board), r;
    if (stereo && !l.empty()) r = FindChessboard(right[i], options.board);
    if (!r.empty()) OrderLike(l, &r);
    if (l.empty() || (stereo && r.empty())) {
      result.board_not_found.push_back(static_cast<int>(i));
      continue;
    }
    result.views_used.push_back(static_cast<int>(i));
    left_views.object.push_back(board);
    left_views.image.push_back(std::move(l));
    if (stereo) {
      right_views.object.push_back(board);
      right_views.image.push_back(std::move(r));
    }
  }
  const int used = static_cast<int>(result.views_used.size());
  if (used < 3) {
    throw InputError(StrCat("the ", options.board.cols, "x", options.board.rows,
                            " board was found in ", used, " of ", left.size(),
                            stereo ? " image pairs" : " images", " (at least 3 needed): ",
                            "is --board the count of inner corners?"));
  }
  result.left = CalibrateOne(left_views, size, options.model);
  if (used < options.min_views) {
    result.warnings.push_back(StrCat("only ", used, " views with the board: take ",
                                     options.min_views, " or more, tilted and across the image"));
  }
  Warn(stereo ? "left" : "", result.left, options, &result.warnings);
  if (!stereo) return result;
  result.right = CalibrateOne(right_views, size, options.model);
  Warn("right", *result.right, options, &result.warnings);
  cv::Mat k1 = CameraMatrix(result.left.camera), d1 = LensCoefficients(result.left.camera);
  cv::Mat k2 = CameraMatrix(result.right->camera), d2 = LensCoefficients(result.right->camera);
  cv::Mat rotation, translation;
  if (options.model == LensModel::kEquidistant) {
    result.stereo_rms_px = cv::fisheye::stereoCalibrate(
        Cast3<double>(left_views.object), Cast2<double>(left_views.image),
        Cast2<double>(right_views.image), k1, d1, k2, d2, size, rotation, translation,
        cv::fisheye::CALIB_FIX_INTRINSIC,
        cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 200, 1e-12));
  } else {
    cv::Mat essential, fundamental;
    result.stereo_rms_px = cv::stereoCalibrate(
        left_views.object, left_views.image, right_views.image, k1, d1, k2, d2, size, rotation,
        translation, essential, fundamental, cv::CALIB_FIX_INTRINSIC);
  }
  Eigen::Matrix3d r;
  Eigen::Vector3d t;
  cv::cv2eigen(rotation, r);
  cv::cv2eigen(translation.reshape(1, 3), t);
  result.right_from_left = Rigid3d(Eigen::Quaterniond(r).normalized(), t);
  if (result.stereo_rms_px > options.max_rms_px) {
    result.warnings.push_back(StrCat("the pair's RMS reprojection error is ",
                                     FormatFixed(result.stereo_rms_px, 2),
                                     " px: were the two images of each pair taken together?"));
  }
  return result;
}

}  // namespace visloc
