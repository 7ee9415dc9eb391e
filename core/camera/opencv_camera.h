#pragma once
// A Camera in OpenCV's terms, for calib3d calls: the intrinsic matrix, and the lens's four
// coefficients as OpenCV orders them (k1 k2 p1 p2 for cv::, k1 k2 k3 k4 for cv::fisheye::).

#include <opencv2/core.hpp>

#include "core/camera/camera.h"

namespace visloc {

cv::Mat CameraMatrix(const Camera& camera);
cv::Mat LensCoefficients(const Camera& camera);

}  // namespace visloc
