#pragma once
// Visibility learning (seed paper 000, sec. 4). For every pair of keyframes i, j the target
//   y_ij = 0.5 (|V_i n V_j| / |V_i| + |V_i n V_j| / |V_j|)                    (eq. 6)
// is the mean share of each keyframe's visible points that the other also sees. The metric A
// of the kernel k_ij = exp(-|| A d_ij ||) (eq. 7, cues in core/map/visibility_kernel.h) is
// fitted to the targets by least squares (Ceres), so that nearby, similarly oriented keyframes,
// which see the same points, score close to 1.

#include <vector>

#include <Eigen/Core>

#include "core/map/map.h"

namespace visloc::mapping {

struct VisibilityLearningOptions {
  int default_k = 10;                          // Paper: K = 10.
  double default_probability_threshold = 0.2;  // Paper: P_t = 0.2.
  int max_pairs = 20000;                       // Subsampled beyond this, deterministically.
};

struct VisibilityLearningStats {
  int pairs = 0;
  double initial_rmse = 0.0;  // Of k_ij - y_ij, with the initial metric.
  double final_rmse = 0.0;
};

// Keyframes and observations of `map` must be filled in. Returns the learned kernel.
VisibilityKernel LearnVisibilityKernel(const Map& map, const VisibilityLearningOptions& options,
                                       VisibilityLearningStats* stats = nullptr);

// The targets y_ij (eq. 6) as a dense symmetric matrix (diagonal 1).
Eigen::MatrixXd VisibilityOverlap(const Map& map);

}  // namespace visloc::mapping
