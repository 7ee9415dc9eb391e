#pragma once
// Least-squares rigid alignment of corresponding point sets (Umeyama, "Least-squares
// estimation of transformation parameters between two point patterns", PAMI 1991).

#include <vector>

#include <Eigen/Core>

#include "core/geometry/rigid3.h"

namespace visloc {

// Returns `target_from_source` minimising sum ||target_i - T * source_i||^2 over rigid T
// (no scale). Throws CheckError for fewer than 3 pairs or mismatched sizes. Collinear input
// leaves the rotation about that line undetermined; the result is then one of the minimisers.
Rigid3d AlignRigid(const std::vector<Eigen::Vector3d>& source,
                   const std::vector<Eigen::Vector3d>& target);

}  // namespace visloc
