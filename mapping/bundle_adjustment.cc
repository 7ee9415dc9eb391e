#include "mapping/bundle_adjustment.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <memory>
#include <optional>

#include "core/util/timer.h"

namespace visloc::mapping {

ObservationError ObservationErrors(const SlamState& state, int l, int k, int i,
                                   const RectifiedIntrinsics& intrinsics) {
  const SlamKeyframe& keyframe = state.keyframes[k];
  const Eigen::Vector3d p = keyframe.cam_from_world * state.landmarks[l].position_in_world;
  ObservationError error;
  if (p.z() <= 1e-6) return {1e9, 1e9};
  const Eigen::Vector2d projected(intrinsics.f * p.x() / p.z() + intrinsics.cx,
                                  intrinsics.f * p.y() / p.z() + intrinsics.cy);
  error.left_px = (projected - keyframe.left_rect[i]).norm();
  error.disparity_px = std::numeric_limits<double>::quiet_NaN();
  if (std::isfinite(keyframe.right_x_rect[i])) {
    const double measured = keyframe.left_rect[i].x() - keyframe.right_x_rect[i];
    error.disparity_px = std::abs(intrinsics.f * intrinsics.baseline_m / p.z() - measured);
  }
  return error;
}

void ApplyDisparityCorrection(const DisparityCorrection& change,
                              const RectifiedIntrinsics& intrinsics, SlamState* state) {
  for (SlamKeyframe& keyframe : state->keyframes) {
    for (double& right_x : keyframe.right_x_rect) {
      if (std::isfinite(right_x)) right_x += change.BiasPx(right_x, intrinsics.f, intrinsics.cx);
    }
  }
}

namespace {

// An observation stays when both errors, in the units bundle adjustment weighs them in, are
// within the threshold.
bool WithinThreshold(const ObservationError& e, const BundleAdjustmentOptions& options) {
  return e.left_px <= options.cull_error_px &&
         (!std::isfinite(e.disparity_px) ||
          options.disparity_weight * e.disparity_px <= options.cull_error_px);
}

// The keyframes an adjustment sees, ascending, and by keyframe index whether each is free and
// its pose block (null outside the window). Flat arrays rather than ordered sets: an adjustment
// looks a keyframe up for each of its thousands of observations.
struct AdjustedWindow {
  std::vector<int> keyframes;
  std::vector<char> free;
  std::vector<PoseBlock*> pose;
  bool Contains(int k) const { return pose[k] != nullptr; }
};

// The elimination order for the Schur solver: points first, then the poses and the correction.
// Ceres would find the same order itself, as an independent set of its graph, at a third of a
// small adjustment's time. Ceres orders a group's blocks by address: the points lie in the
// landmark vector and the camera blocks in one allocation (BundleAdjust), both in index order,
// so every solve sums in the same order whatever the allocator did before (the same map for
// any thread count).
std::shared_ptr<ceres::ParameterBlockOrdering> PointsFirst(const ceres::Problem& problem,
                                                           const std::vector<int>& landmarks,
                                                           SlamState* state,
                                                           const AdjustedWindow& window,
                                                           double* correction) {
  auto ordering = std::make_shared<ceres::ParameterBlockOrdering>();
  for (int l : landmarks) {
    double* point = state->landmarks[l].position_in_world.data();
    if (problem.HasParameterBlock(point)) ordering->AddElementToGroup(point, 0);
  }
  for (int k : window.keyframes) {
    PoseBlock* pose = window.pose[k];
    if (!problem.HasParameterBlock(pose->data())) continue;
    ordering->AddElementToGroup(pose->data(), 1);
    ordering->AddElementToGroup(pose->data() + 4, 1);
  }
  if (problem.HasParameterBlock(correction)) ordering->AddElementToGroup(correction, 1);
  return ordering;
}

// Below this many keyframes the reduced camera matrix is small enough that a dense Cholesky
// factorization costs nothing beside building it (a local window: 10).
constexpr size_t kSparseFromKeyframes = 64;
// Above this share of keyframe pairs that share a point, the reduced camera matrix is as good as
// dense. A sparse factorization pays for its symbolic analysis and loses the dense kernels' speed:
// 60 keyframes of a drive that all see the same far points adjust in 2.1 s dense against 3.0 s
// sparse (mapping_benchmark), while the generated five-room suite's 863 keyframes, each of which
// shares points with a few dozen others, adjust in half the time sparse.
constexpr double kSparseBelowDensity = 0.3;

// The linear solver for an adjustment whose points are `landmarks` (those with two or more
// observations in the window): dense Schur for small or densely connected windows, sparse Schur
// (SuiteSparse) for a long run's, whose keyframes share points with their neighbours only.
ceres::LinearSolverType SchurSolverFor(const std::vector<int>& landmarks,
                                       const AdjustedWindow& window, const SlamState& state) {
  const size_t n = window.keyframes.size();
  if (n < kSparseFromKeyframes) return ceres::DENSE_SCHUR;
  std::vector<int> position(window.pose.size(), -1);  // Keyframe index -> row in the window.
  for (size_t j = 0; j < n; ++j) position[window.keyframes[j]] = static_cast<int>(j);
  std::vector<char> covisible(n * n, 0);
  size_t pairs = 0;
  std::vector<int> rows;
  for (int l : landmarks) {
    rows.clear();
    for (const auto& [k, i] : state.landmarks[l].observations) {
      if (position[k] >= 0) rows.push_back(position[k]);
    }
    for (size_t a = 0; a < rows.size(); ++a) {
      for (size_t b = a + 1; b < rows.size(); ++b) {
        char& seen = covisible[std::min(rows[a], rows[b]) * n + std::max(rows[a], rows[b])];
        pairs += !seen;
        seen = 1;
      }
    }
  }
  const double density = static_cast<double>(pairs) / (0.5 * n * (n - 1));
  return density < kSparseBelowDensity ? ceres::SPARSE_SCHUR : ceres::DENSE_SCHUR;
}

// Moves landmark `l` to fit keyframe k's keypoint i exactly, as bundle adjustment would at no
// cost when that is the landmark's only observation in the problem: to the depth its disparity
// gives, or along its ray at its depth in the camera when the observation is left-only (or its
// disparity is not positive).
void FitToObservation(int l, int k, int i, const RectifiedIntrinsics& intrinsics,
                      SlamState* state) {
  const SlamKeyframe& keyframe = state->keyframes[k];
  Landmark& landmark = state->landmarks[l];
  const Eigen::Vector2d& left = keyframe.left_rect[i];
  const double disparity_px = left.x() - keyframe.right_x_rect[i];  // NaN when left-only.
  double z = (keyframe.cam_from_world * landmark.position_in_world).z();
  if (disparity_px > 0) z = intrinsics.f * intrinsics.baseline_m / disparity_px;
  if (!(z > 0)) return;  // Behind the camera: no fit, and the cull takes it.
  const Eigen::Vector3d point_in_cam((left.x() - intrinsics.cx) * z / intrinsics.f,
                                     (left.y() - intrinsics.cy) * z / intrinsics.f, z);
  landmark.position_in_world = keyframe.cam_from_world.Inverse() * point_in_cam;
}

}  // namespace

BundleAdjustmentSummary BundleAdjust(SlamState* state, const std::vector<int>& free_keyframes,
                                     const std::vector<int>& fixed_keyframes,
                                     const RectifiedIntrinsics& intrinsics,
                                     const BundleAdjustmentOptions& options) {
  Timer timer;
  BundleAdjustmentSummary summary;
  const int keyframe_count = static_cast<int>(state->keyframes.size());
  AdjustedWindow window;
  window.free.assign(keyframe_count, 0);
  window.pose.assign(keyframe_count, nullptr);
  window.keyframes = fixed_keyframes;
  for (int k : free_keyframes) {
    window.free[k] = 1;
    window.keyframes.push_back(k);
  }
  std::sort(window.keyframes.begin(), window.keyframes.end());
  window.keyframes.erase(std::unique(window.keyframes.begin(), window.keyframes.end()),
                         window.keyframes.end());
  std::vector<int> landmarks;  // Those the free keyframes observe, ascending.
  for (int k : free_keyframes) {
    for (int l : state->keyframes[k].landmark) {
      if (l >= 0 && !state->landmarks[l].culled) landmarks.push_back(l);
    }
  }
  std::sort(landmarks.begin(), landmarks.end());
  landmarks.erase(std::unique(landmarks.begin(), landmarks.end()), landmarks.end());
  // The parameters besides the points, copied in and written back afterwards: the window's
  // poses in keyframe order, then the change of the disparity correction (offset px, yaw rad,
  // the unused entry; reprojection_cost.h) in the first entries of one more block, all in one
  // allocation in index order (PointsFirst).
  std::vector<PoseBlock> camera_blocks(window.keyframes.size() + 1);
  for (size_t j = 0; j < window.keyframes.size(); ++j) {
    const int k = window.keyframes[j];
    camera_blocks[j] = ToPoseBlock(state->keyframes[k].cam_from_world);
    window.pose[k] = &camera_blocks[j];
  }
  static_assert(kCorrectionBlockSize <= std::tuple_size_v<PoseBlock>);
  camera_blocks.back().fill(0.0);
  double* correction_change = camera_blocks.back().data();
  ceres::Problem problem;
  ceres::LossFunction* loss = new ceres::HuberLoss(options.huber_px);  // shared, owned by problem
  double initial_sq = 0;
  int residual_count = 0;
  // A landmark the window sees once says nothing about the poses or the correction: its
  // coordinates fit that observation exactly whatever they are (three residuals, three
  // unknowns; a left-only observation leaves its depth free), so it adds no cost anywhere. Left
  // out of the problem and fitted afterwards (FitToObservation), it ends where the solver would
  // have taken it, and the solver eliminates fewer points: a KITTI 01 build's local adjustments
  // have half their landmarks so, its global ones 60% (28% of the residuals).
  std::vector<std::array<int, 3>> seen_once;  // (landmark, keyframe, keypoint)
  std::vector<int> problem_landmarks;         // Those seen twice or more: in the problem.
  for (int l : landmarks) {
    Landmark& landmark = state->landmarks[l];
    std::optional<std::pair<int, int>> only;
    int in_window = 0;
    for (const auto& [k, i] : landmark.observations) {
      if (window.Contains(k) && ++in_window == 1) only.emplace(k, i);
    }
    if (in_window == 1) {
      seen_once.push_back({l, only->first, only->second});
      const double e = ObservationErrors(*state, l, only->first, only->second, intrinsics).left_px;
      initial_sq += e * e;
      continue;
    }
    problem_landmarks.push_back(l);
    for (const auto& [k, i] : landmark.observations) {
      if (!window.Contains(k)) continue;
      const SlamKeyframe& keyframe = state->keyframes[k];
      double* pose = window.pose[k]->data();
      const double right_x = keyframe.right_x_rect[i];
      // Every observation has the stereo layout, the left-only ones with a zero disparity row:
      // one row size lets Ceres eliminate the points with its fixed-size code.
      ceres::CostFunction* cost =
          std::isfinite(right_x)
              ? StereoReprojectionCost::Create(keyframe.left_rect[i], right_x, intrinsics,
                                               options.disparity_weight)
              : StereoReprojectionCost::LeftOnly(keyframe.left_rect[i], intrinsics);
      problem.AddResidualBlock(cost, loss, pose, pose + 4, landmark.position_in_world.data(),
                               correction_change);
      const double e = ObservationErrors(*state, l, k, i, intrinsics).left_px;
      initial_sq += e * e;
      ++residual_count;
    }
  }
  summary.keyframes = static_cast<int>(window.keyframes.size());
  summary.landmarks = static_cast<int>(landmarks.size());
  summary.residual_blocks = residual_count;
  if (residual_count == 0) return summary;  // Nothing moves, so what fitted still fits.
  for (int k : window.keyframes) SetUpPoseBlock(&problem, window.pose[k], !window.free[k]);
  if (problem.HasParameterBlock(correction_change)) {
    if (options.estimate_disparity_correction) {
      problem.AddResidualBlock(
          DisparityCorrectionPrior::Create(options.correction_offset_sigma_px,
                                           options.correction_yaw_sigma_deg * M_PI / 180.0),
          nullptr, correction_change);
    } else {
      problem.SetParameterBlockConstant(correction_change);
    }
  }
  summary.iterations = SolveQuietly(
      &problem, SchurSolverFor(problem_landmarks, window, *state), options.max_iterations,
      PointsFirst(problem, landmarks, state, window, correction_change),
      options.function_tolerance);
  for (int k : window.keyframes) {
    state->keyframes[k].cam_from_world = FromPoseBlock(*window.pose[k]);
  }
  summary.correction_change = {correction_change[0], correction_change[1]};
  if (options.estimate_disparity_correction) {
    ApplyDisparityCorrection(summary.correction_change, intrinsics, state);
  }
  for (const auto& [l, k, i] : seen_once) FitToObservation(l, k, i, intrinsics, state);
  // Cull: observations above the error threshold, then landmarks seen fewer than twice.
  double final_sq = 0;
  int final_count = 0;
  for (int l : landmarks) {
    Landmark& landmark = state->landmarks[l];
    std::vector<std::pair<int, int>> kept;
    for (const auto& [k, i] : landmark.observations) {
      const ObservationError e = ObservationErrors(*state, l, k, i, intrinsics);
      if (window.Contains(k)) {
        final_sq += std::min(e.left_px * e.left_px, 100.0);
        ++final_count;
      }
      if (WithinThreshold(e, options)) {
        kept.emplace_back(k, i);
      } else {
        state->keyframes[k].landmark[i] = -1;
        ++summary.culled_observations;
      }
    }
    landmark.observations = std::move(kept);
    if (landmark.observations.empty()) landmark.culled = true;
  }
  summary.initial_rmse_px =
      std::sqrt(initial_sq / (residual_count + static_cast<int>(seen_once.size())));
  summary.final_rmse_px = final_count ? std::sqrt(final_sq / final_count) : 0.0;
  summary.time_ms = timer.ElapsedMs();
  return summary;
}

}  // namespace visloc::mapping
