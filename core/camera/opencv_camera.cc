#include "core/camera/opencv_camera.h"

#include <opencv2/core/eigen.hpp>

namespace visloc {

cv::Mat CameraMatrix(const Camera& camera) {
  cv::Mat k;
  cv::eigen2cv(camera.K(), k);
  return k;
}

cv::Mat LensCoefficients(const Camera& camera) {
  const auto& c = camera.lens().coefficients;
  return (cv::Mat_<double>(1, 4) << c[0], c[1], c[2], c[3]);
}

}  // namespace visloc
