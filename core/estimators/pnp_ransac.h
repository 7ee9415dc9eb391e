#pragma once
// Robust camera pose from 3D-2D correspondences: RANSAC over the P3P minimal solver, then
// Levenberg-Marquardt on the inliers (seed paper 000, sec. 5). The iteration count adapts to
// the inlier ratio found so far (stop when a better model is unlikely at `confidence`).

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "core/estimators/pose_refinement.h"

namespace visloc {

struct PnpRansacOptions {
  double max_error_px = 2.0;  // Inlier threshold (paper: 2 px).
  int max_iterations = 500;
  int min_iterations = 5;
  double confidence = 0.999;
  int min_inliers = 8;
  // Select-inliers-and-refine passes after RANSAC (or on a given pose), at least 1.
  int refinement_passes = 2;
  uint64_t seed = 1;  // Sampling is deterministic given the seed.
  PoseRefineOptions refine;
  void Check() const;
};

struct PnpStats {
  int iterations = 0;  // RANSAC hypotheses tried.
  // A rig's RANSAC: how many of the cameras' best hypotheses were refined (SolveRigPnpRansac).
  int local_refinements = 0;
  int inliers = 0;
  double inlier_ratio = 0.0;
  PoseRefineStats refine;
};

struct PnpResult {
  bool success = false;
  Rigid3d cam_from_world;
  std::vector<char> inlier_mask;  // One per observation.
  Eigen::Matrix<double, 6, 6> covariance = Eigen::Matrix<double, 6, 6>::Zero();
  PnpStats stats;
};

PnpResult SolvePnpRansac(const std::vector<PoseObservation>& observations,
                         const PnpRansacOptions& options);

// The second half of SolvePnpRansac, for a pose from elsewhere (a prior, or a pose re-matched
// with more correspondences): selects the observations within max_error_px, refines on them,
// re-selects and refines again. `stats.iterations` is 0.
PnpResult RefinePoseOnInliers(const Rigid3d& cam_from_world,
                              const std::vector<PoseObservation>& observations,
                              const PnpRansacOptions& options);

// The same over a rig of cameras (RigObservations): hypotheses from P3P within one camera (a
// camera drawn in proportion to its observations), scored by the inliers of every camera
// under the rig's pose; the refinement then fits the reference camera's pose to all of them.
// Generalized minimal solvers (a non-central P3P) sample across cameras too, but a rig's
// cameras each see tens of matches and more, where sampling within one loses nothing.
struct RigPnpResult {
  bool success = false;
  Rigid3d ref_from_world;
  std::vector<std::vector<char>> inlier_masks;  // Per camera, one per observation.
  std::vector<int> camera_inliers;
  Eigen::Matrix<double, 6, 6> covariance = Eigen::Matrix<double, 6, 6>::Zero();  // Reference frame.
  PnpStats stats;  // Over all cameras.
};

RigPnpResult SolveRigPnpRansac(const RigObservations& rig, const PnpRansacOptions& options);

// RefinePoseOnInliers over a rig.
RigPnpResult RefineRigPoseOnInliers(const Rigid3d& ref_from_world, const RigObservations& rig,
                                    const PnpRansacOptions& options);

}  // namespace visloc
