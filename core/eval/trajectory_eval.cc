#include "core/eval/trajectory_eval.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <tuple>

#include <Eigen/Cholesky>

#include "core/geometry/align.h"
#include "core/util/check.h"

namespace visloc {

void EvalOptions::Check() const {
  VISLOC_CHECK(max_time_diff_s >= 0.0, "max_time_diff_s ", max_time_diff_s);
  VISLOC_CHECK(rpe_delta_s > 0.0, "rpe_delta_s ", rpe_delta_s);
}

ErrorStats ComputeErrorStats(std::vector<double> errors) {
  ErrorStats stats;
  stats.count = errors.size();
  if (errors.empty()) return stats;
  const double n = static_cast<double>(errors.size());
  double sum = 0.0, sum_sq = 0.0;
  for (double e : errors) {
    sum += e;
    sum_sq += e * e;
  }
  stats.mean = sum / n;
  stats.rmse = std::sqrt(sum_sq / n);
  stats.std_dev = std::sqrt(std::max(0.0, sum_sq / n - stats.mean * stats.mean));
  std::sort(errors.begin(), errors.end());
  stats.min = errors.front();
  stats.max = errors.back();
  const size_t mid = errors.size() / 2;
  stats.median = errors.size() % 2 ? errors[mid] : 0.5 * (errors[mid - 1] + errors[mid]);
  const size_t rank = static_cast<size_t>(std::ceil(0.95 * n));
  stats.p95 = errors[std::clamp<size_t>(rank, 1, errors.size()) - 1];
  return stats;
}

std::vector<std::pair<size_t, size_t>> AssociateByTime(const Trajectory& gt, const Trajectory& est,
                                                       double max_time_diff_s) {
  const int64_t max_diff_ns = SecondsToNs(max_time_diff_s);
  // Candidate pairs: each estimate with its nearest ground-truth neighbours in time.
  std::vector<std::tuple<int64_t, size_t, size_t>> candidates;  // (|dt|, gt, est)
  for (size_t e = 0; e < est.size(); ++e) {
    const int64_t t = est[e].timestamp_ns;
    const auto it = std::lower_bound(gt.begin(), gt.end(), t, [](const StampedPose& p, int64_t x) {
      return p.timestamp_ns < x;
    });
    const size_t upper = static_cast<size_t>(it - gt.begin());
    for (size_t g : {upper, upper - 1}) {  // upper - 1 wraps when upper == 0; rejected below
      if (g >= gt.size()) continue;
      const int64_t diff = std::llabs(gt[g].timestamp_ns - t);
      if (diff <= max_diff_ns) candidates.emplace_back(diff, g, e);
    }
  }
  std::sort(candidates.begin(), candidates.end());
  std::vector<bool> gt_used(gt.size(), false), est_used(est.size(), false);
  std::vector<std::pair<size_t, size_t>> pairs;
  for (const auto& [diff, g, e] : candidates) {
    if (gt_used[g] || est_used[e]) continue;
    gt_used[g] = est_used[e] = true;
    pairs.emplace_back(g, e);
  }
  std::sort(pairs.begin(), pairs.end());
  return pairs;
}

namespace {

PoseErrors AbsoluteErrors(const std::vector<Rigid3d>& gt, const std::vector<Rigid3d>& est,
                          const Rigid3d& gt_from_est) {
  std::vector<double> translation, rotation;
  for (size_t i = 0; i < gt.size(); ++i) {
    const Rigid3d aligned = gt_from_est * est[i];
    translation.push_back((gt[i].translation - aligned.translation).norm());
    rotation.push_back(RotationAngleDeg(gt[i].rotation.conjugate() * aligned.rotation));
  }
  return {ComputeErrorStats(translation), ComputeErrorStats(rotation)};
}

PoseErrors RelativeErrors(const std::vector<int64_t>& times_ns, const std::vector<Rigid3d>& gt,
                          const std::vector<Rigid3d>& est, const EvalOptions& options) {
  const int64_t delta_ns = SecondsToNs(options.rpe_delta_s);
  // A pair counts when its separation is within 10% of delta (or the association tolerance),
  // so gaps in the estimate do not turn into RPE over much longer intervals.
  const int64_t tolerance_ns = std::max(delta_ns / 10, SecondsToNs(options.max_time_diff_s));
  std::vector<double> translation, rotation;
  size_t j = 0;
  for (size_t i = 0; i < times_ns.size(); ++i) {
    const int64_t wanted = times_ns[i] + delta_ns;
    j = std::max(j, i + 1);
    while (j + 1 < times_ns.size() &&
           std::llabs(times_ns[j + 1] - wanted) <= std::llabs(times_ns[j] - wanted)) {
      ++j;
    }
    if (j >= times_ns.size() || std::llabs(times_ns[j] - wanted) > tolerance_ns) continue;
    const Rigid3d gt_motion = gt[i].Inverse() * gt[j];
    const Rigid3d est_motion = est[i].Inverse() * est[j];
    const Rigid3d error = gt_motion.Inverse() * est_motion;
    translation.push_back(error.translation.norm());
    rotation.push_back(RotationAngleDeg(error.rotation));
  }
  return {ComputeErrorStats(translation), ComputeErrorStats(rotation)};
}

// The ground truth as the comparison sees it (relative to its first pose, when asked).
Trajectory ComparedGroundTruth(const Trajectory& gt, const EvalOptions& options) {
  if (!options.gt_origin_first || gt.empty()) return gt;
  const Rigid3d first_from_world = gt.front().pose.Inverse();
  Trajectory relative = gt;
  for (StampedPose& p : relative) p.pose = first_from_world * p.pose;
  return relative;
}

// ATE per distance leaves out the poses before the ground truth has travelled this far: a share of
// a few centimetres is noise (a still camera's ground truth wanders by millimetres).
constexpr double kMinTravelM = 0.5;

// Distance travelled along the ground truth from its first pose, per ground-truth pose (m).
std::vector<double> DistanceTravelled(const Trajectory& gt) {
  std::vector<double> distance(gt.size(), 0.0);
  for (size_t i = 1; i < gt.size(); ++i) {
    distance[i] = distance[i - 1] + (gt[i].pose.translation - gt[i - 1].pose.translation).norm();
  }
  return distance;
}

}  // namespace

TrajectoryEvaluation EvaluateTrajectory(const Trajectory& gt_as_given, const Trajectory& est,
                                        const EvalOptions& options) {
  options.Check();
  const Trajectory gt = ComparedGroundTruth(gt_as_given, options);
  const std::vector<double> travelled_m = DistanceTravelled(gt);
  TrajectoryEvaluation result;
  result.gt_poses = gt.size();
  result.est_poses = est.size();
  const auto pairs = AssociateByTime(gt, est, options.max_time_diff_s);
  result.matched_poses = pairs.size();
  result.coverage = gt.empty() ? 0.0 : static_cast<double>(pairs.size()) / gt.size();

  std::vector<int64_t> times_ns;
  std::vector<Rigid3d> gt_poses, est_poses;
  std::vector<Eigen::Vector3d> gt_positions, est_positions;
  std::vector<double> per_distance;
  for (const auto& [g, e] : pairs) {
    if (travelled_m[g] >= kMinTravelM) {
      per_distance.push_back((gt[g].pose.translation - est[e].pose.translation).norm() /
                             travelled_m[g]);
    }
    times_ns.push_back(gt[g].timestamp_ns);
    gt_poses.push_back(gt[g].pose);
    est_poses.push_back(est[e].pose);
    gt_positions.push_back(gt[g].pose.translation);
    est_positions.push_back(est[e].pose.translation);
  }
  result.ate = AbsoluteErrors(gt_poses, est_poses, Rigid3d::Identity());
  result.ate_per_distance = ComputeErrorStats(std::move(per_distance));
  if (options.align) {
    if (pairs.size() >= 3) result.gt_from_est = AlignRigid(est_positions, gt_positions);
    result.ate_aligned = AbsoluteErrors(gt_poses, est_poses, result.gt_from_est);
  }
  result.rpe = RelativeErrors(times_ns, gt_poses, est_poses, options);
  return result;
}

ConsistencyEvaluation EvaluateConsistency(const Trajectory& gt_as_given, const Trajectory& est,
                                          const std::vector<Eigen::Matrix3d>& position_covariance_m2,
                                          const EvalOptions& options) {
  options.Check();
  VISLOC_CHECK(position_covariance_m2.size() == est.size(), position_covariance_m2.size(),
               " covariances for ", est.size(), " estimates");
  const Trajectory gt = ComparedGroundTruth(gt_as_given, options);
  std::vector<double> normalized;
  for (const auto& [g, e] : AssociateByTime(gt, est, options.max_time_diff_s)) {
    const Eigen::LLT<Eigen::Matrix3d> factor(position_covariance_m2[e]);
    if (!position_covariance_m2[e].allFinite() || factor.info() != Eigen::Success ||
        !(position_covariance_m2[e].trace() > 0)) {
      continue;  // None reported.
    }
    const Eigen::Vector3d error = gt[g].pose.translation - est[e].pose.translation;
    // |L^-1 e| = sqrt(e^T Sigma^-1 e) for Sigma = L L^T.
    normalized.push_back(factor.matrixL().solve(error).norm());
  }
  ConsistencyEvaluation result;
  result.compared = normalized.size();
  for (double z : normalized) {
    result.beyond_3_sigma += z > 3.0;
    result.beyond_6_sigma += z > 6.0;
  }
  if (!normalized.empty()) {
    result.beyond_3_sigma /= static_cast<double>(normalized.size());
    result.beyond_6_sigma /= static_cast<double>(normalized.size());
  }
  result.normalized_error = ComputeErrorStats(std::move(normalized));
  return result;
}

TrajectorySpread ComputeSpread(const Trajectory& poses) {
  TrajectorySpread spread;
  spread.poses = poses.size();
  if (poses.empty()) return spread;
  Eigen::Vector4d quaternion_sum = Eigen::Vector4d::Zero();
  const Eigen::Vector4d first = poses.front().pose.rotation.coeffs();
  for (const StampedPose& p : poses) {
    spread.mean_position += p.pose.translation;
    const Eigen::Vector4d q = p.pose.rotation.coeffs();
    quaternion_sum += q.dot(first) < 0 ? -q : q;  // q and -q are the same rotation
  }
  spread.mean_position /= static_cast<double>(poses.size());
  const Eigen::Quaterniond mean_rotation = Eigen::Quaterniond(quaternion_sum).normalized();
  std::vector<double> position, rotation;
  for (const StampedPose& p : poses) {
    position.push_back((p.pose.translation - spread.mean_position).norm());
    rotation.push_back(RotationAngleDeg(mean_rotation.inverse() * p.pose.rotation));
  }
  spread.position_m = ComputeErrorStats(std::move(position));
  spread.rotation_deg = ComputeErrorStats(std::move(rotation));
  return spread;
}

}  // namespace visloc
