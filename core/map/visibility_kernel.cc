#include "core/map/visibility_kernel.h"

#include <cmath>

#include "core/util/check.h"

namespace visloc {

Eigen::Vector2d KernelCues(const Eigen::Vector3d& center_i, const Eigen::Vector3d& view_i,
                           const Eigen::Vector3d& center_j, const Eigen::Vector3d& view_j) {
  return Eigen::Vector2d((center_i - center_j).norm(), 1.0 - view_i.dot(view_j));
}

double EvaluateKernel(const Eigen::MatrixXd& metric, const Eigen::Vector2d& cues) {
  VISLOC_CHECK(metric.rows() == 2 && metric.cols() == 2, "kernel metric must be 2x2");
  return std::exp(-(metric * cues).norm());
}

}  // namespace visloc
