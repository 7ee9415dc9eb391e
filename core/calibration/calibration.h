#pragma once
// Camera calibration from views of a chessboard (Zhang's method through OpenCV): inner corners
// found and refined to sub-pixel, intrinsics and lens coefficients by calibrateCamera (the
// radial-tangential model: k1 k2 p1 p2, k3 held at 0 as visloc's camera has none) or
// cv::fisheye::calibrate (equidistant k1..k4), and for a stereo pair the right camera's pose from
// stereoCalibrate with each camera's intrinsics held. Reprojection errors are measured with
// visloc's own Camera, so the figures are those of the model that maps and localizes.
//
// Frames: the board lies in its z = 0 plane, corners at (c s, r s, 0) for column c and row r,
// s the square size (metres). right_from_left maps left-camera coordinates into the right
// camera, as the datasets store it.

#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "core/camera/camera.h"
#include "core/geometry/rigid3.h"

namespace visloc {

struct ChessboardSpec {
  int cols = 9;  // Inner corners per row.
  int rows = 6;  // Inner corners per column.
  double square_m = 0.025;
  void Check() const;
};

// The board's inner corners in an 8-bit grey image, refined to sub-pixel, row by row; empty
// when the board is not found whole.
std::vector<cv::Point2f> FindChessboard(const cv::Mat& grey, const ChessboardSpec& board);

struct CalibrationOptions {
  ChessboardSpec board;
  LensModel model = LensModel::kRadialTangential;
  // Warnings: a calibration is weak with fewer views, with corners in fewer cells of an 8x6
  // grid over the image, or with a larger RMS reprojection error.
  int min_views = 10;
  double min_coverage = 0.5;
  double max_rms_px = 1.0;
  void Check() const;
};

struct CameraCalibration {
  Camera camera;
  double rms_px = 0.0;              // Over every corner of every view used.
  std::vector<double> view_rms_px;  // Per view used.
  double coverage = 0.0;            // Share of the 8x6 cells of the image holding corners.
};

struct CalibrationResult {
  CameraCalibration left;
  std::optional<CameraCalibration> right;  // Stereo only.
  Rigid3d right_from_left;                 // Stereo only.
  double stereo_rms_px = 0.0;              // Both images, the right through right_from_left.
  std::vector<int> views_used;             // Indices of the image (pairs) used.
  std::vector<int> board_not_found;        // Indices where the board was not found (in both).
  std::vector<std::string> warnings;       // Why the calibration may be weak.
};

// Mono when `right` is empty; else `left` and `right` are pairs taken at the same moments.
// Images are 8-bit grey of one size. Throws InputError when too few views show the board (3).
CalibrationResult Calibrate(const std::vector<cv::Mat>& left, const std::vector<cv::Mat>& right,
                            const CalibrationOptions& options);

}  // namespace visloc
