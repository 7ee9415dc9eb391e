#include "core/estimators/p3p.h"

#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>

namespace visloc {

std::vector<Rigid3d> SolveP3P(const std::array<Eigen::Vector3d, 3>& points_in_world,
                              const std::array<Eigen::Vector2d, 3>& normalized) {
  cv::Mat object(3, 3, CV_64F), image(3, 2, CV_64F);
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) object.at<double>(i, j) = points_in_world[i][j];
    image.at<double>(i, 0) = normalized[i].x();
    image.at<double>(i, 1) = normalized[i].y();
  }
  std::vector<cv::Mat> rvecs, tvecs;
  const cv::Mat identity = cv::Mat::eye(3, 3, CV_64F);
  int count = 0;
  try {
    count = cv::solveP3P(object, image, identity, cv::Mat(), rvecs, tvecs, cv::SOLVEPNP_AP3P);
  } catch (const cv::Exception&) {
    return {};  // degenerate configuration
  }
  std::vector<Rigid3d> solutions;
  for (int i = 0; i < count; ++i) {
    cv::Mat rotation;
    cv::Rodrigues(rvecs[i], rotation);
    Eigen::Matrix3d r;
    Eigen::Vector3d t;
    cv::cv2eigen(rotation, r);
    cv::cv2eigen(tvecs[i], t);
    if (r.allFinite() && t.allFinite()) solutions.emplace_back(r, t);
  }
  return solutions;
}

}  // namespace visloc
