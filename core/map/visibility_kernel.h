#pragma once
// Evaluation of the learned visibility kernel (seed paper 000, eq. 7). The cues between two
// camera poses i and j are
//   d_ij = ( ||c_i - c_j||  [metres, camera centres],  1 - v_i . v_j  [viewing directions] ),
// and k_ij = exp(-|| A d_ij ||_2) with the learned metric A. k is 1 for identical poses and
// falls towards 0 as the poses' visible point sets stop overlapping.

#include <Eigen/Core>

#include "core/map/map.h"

namespace visloc {

// The cue names used by this visloc; a map whose kernel has other cues is refused.
inline const std::vector<std::string>& KernelCueNames() {
  static const std::vector<std::string> names = {"translation_m", "view_direction"};
  return names;
}

Eigen::Vector2d KernelCues(const Eigen::Vector3d& center_i, const Eigen::Vector3d& view_i,
                           const Eigen::Vector3d& center_j, const Eigen::Vector3d& view_j);

double EvaluateKernel(const Eigen::MatrixXd& metric, const Eigen::Vector2d& cues);

}  // namespace visloc
