#pragma once
// The minimal absolute pose problem: the camera pose from three 3D points and their bearings.
// Finds cam_from_world such that cam_from_world * point_i is parallel to bearing_i (i = 1..3);
// up to four solutions. Solver: Ke and Roumeliotis, "An Efficient Algebraic Solution to the
// Perspective-Three-Point Problem", CVPR 2017 (OpenCV's SOLVEPNP_AP3P).

#include <array>
#include <vector>

#include <Eigen/Core>

#include "core/geometry/rigid3.h"

namespace visloc {

// `normalized[i]` is the bearing (x/z, y/z) of `points_in_world[i]`. Degenerate input
// (collinear points) yields no solution.
std::vector<Rigid3d> SolveP3P(const std::array<Eigen::Vector3d, 3>& points_in_world,
                              const std::array<Eigen::Vector2d, 3>& normalized);

}  // namespace visloc
