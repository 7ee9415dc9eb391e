#pragma once
// Trajectory accuracy as in the TUM RGB-D benchmark (Sturm et al., IROS 2012) and the evo tool:
//
// - Association: each estimated pose is paired with the ground-truth pose nearest in time,
//   at most `max_time_diff_s` apart, greedily by smallest difference, each pose used once.
// - ATE (absolute trajectory error): for each pair, the translation error ||t_gt - t_est|| in
//   metres and the rotation error angle(R_gt^T R_est) in degrees. Without alignment the
//   estimate is compared in the map frame as is (what a robot would act on); with alignment it
//   is first moved by the SE(3) transform that best fits its positions to the ground truth
//   (Umeyama, no scale), which isolates the trajectory's shape from a frame offset.
// - RPE (relative pose error) over a time delta: for pairs i, j with t_j - t_i ~ delta,
//   E = (gt_i^-1 gt_j)^-1 (est_i^-1 est_j); translation ||t_E|| m and rotation angle(E) deg.
//   RPE measures drift and does not depend on the frame the estimate is expressed in.
// - ATE per distance: each pair's translation error over the distance the ground truth has
//   travelled from its first pose to that pose (pairs in its first half metre are left out):
//   drift as a share of the path, e.g. keyframes of an outdoor map against the path driven.
// - Coverage: the share of ground-truth poses that have an associated estimate, i.e. the
//   share of frames localized when the ground truth has one pose per frame.

#include <cstddef>
#include <optional>
#include <vector>

#include "core/geometry/trajectory.h"

namespace visloc {

struct EvalOptions {
  double max_time_diff_s = 0.02;  // Association tolerance (TUM associate.py default).
  bool align = false;             // Also report ATE after SE(3) alignment.
  // Express the ground truth relative to its own first pose before comparing: the map frame
  // when the map was built from the recording's first frame (a recording's ground truth lives
  // in its own world frame).
  bool gt_origin_first = false;
  double rpe_delta_s = 1.0;  // RPE interval (TUM evaluate_rpe.py default).
  void Check() const;
};

struct ErrorStats {
  size_t count = 0;
  double rmse = 0.0;
  double mean = 0.0;
  double median = 0.0;
  double std_dev = 0.0;
  double min = 0.0;
  double max = 0.0;
  double p95 = 0.0;  // 95th percentile (nearest rank).
};

// Statistics of a list of non-negative errors (all zero for an empty list).
ErrorStats ComputeErrorStats(std::vector<double> errors);

struct PoseErrors {
  ErrorStats translation_m;
  ErrorStats rotation_deg;
};

struct TrajectoryEvaluation {
  size_t gt_poses = 0;
  size_t est_poses = 0;
  size_t matched_poses = 0;
  double coverage = 0.0;                  // matched_poses / gt_poses, in [0, 1].
  PoseErrors ate;                         // In the map frame, no alignment.
  ErrorStats ate_per_distance;            // ATE translation / distance travelled (fraction).
  std::optional<PoseErrors> ate_aligned;  // With EvalOptions::align.
  Rigid3d gt_from_est;                    // The alignment used for ate_aligned.
  PoseErrors rpe;
};

// Pairs (gt index, est index) per the association rule above, sorted by gt time.
std::vector<std::pair<size_t, size_t>> AssociateByTime(const Trajectory& gt, const Trajectory& est,
                                                       double max_time_diff_s);

// Both trajectories must be sorted by time. Fewer than 3 associated poses leave the alignment
// at identity (and ate_aligned equal to ate).
TrajectoryEvaluation EvaluateTrajectory(const Trajectory& gt, const Trajectory& est,
                                        const EvalOptions& options);

// Whether the reported uncertainty tells the truth: each estimate's position error e in units of
// its covariance Sigma, the Mahalanobis distance sqrt(e^T Sigma^-1 e) (|e| / sigma for an
// isotropic Sigma = sigma^2 I). For an honest Gaussian it follows a chi distribution with 3
// degrees of freedom: median 1.54, 2.9% beyond 3 and none in practice beyond 6 (1 in 10^7).
struct ConsistencyEvaluation {
  size_t compared = 0;          // Estimates with a ground-truth pose and a covariance.
  ErrorStats normalized_error;  // sqrt(error^T Sigma^-1 error).
  double beyond_3_sigma = 0.0;  // Share of the compared estimates.
  double beyond_6_sigma = 0.0;
};

// `position_covariance_m2` holds one position covariance (map frame, m^2) per estimate of `est`
// (not positive definite, e.g. zero: none reported).
ConsistencyEvaluation EvaluateConsistency(const Trajectory& gt, const Trajectory& est,
                                          const std::vector<Eigen::Matrix3d>& position_covariance_m2,
                                          const EvalOptions& options);

// How far the poses of a trajectory scatter about their mean: the jitter of a camera that stands
// still, with no ground truth needed. Deviations of each position from the mean position (m)
// and of each rotation from the mean rotation (deg; the normalized mean of sign-aligned
// quaternions, which is the rotation mean for rotations this close together).
struct TrajectorySpread {
  size_t poses = 0;
  Eigen::Vector3d mean_position = Eigen::Vector3d::Zero();
  ErrorStats position_m;
  ErrorStats rotation_deg;
};
TrajectorySpread ComputeSpread(const Trajectory& poses);

}  // namespace visloc
