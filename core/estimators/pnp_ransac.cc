#include "core/estimators/pnp_ransac.h"

#include <algorithm>
#include <array>
#include <cmath>

#include "core/estimators/inlier_counter.h"
#include "core/estimators/p3p.h"
#include "core/util/check.h"
#include "core/util/random.h"

namespace visloc {

void PnpRansacOptions::Check() const {
  VISLOC_CHECK(max_error_px > 0 && max_iterations >= 1 && min_iterations >= 1 && confidence > 0 &&
                   confidence < 1 && min_inliers >= 3 && refinement_passes >= 1,
               "PnP RANSAC options");
  refine.Check();
}

namespace {

int CountInliers(const Rigid3d& pose, const std::vector<PoseObservation>& observations,
                 const PnpRansacOptions& options, std::vector<char>* mask) {
  const double threshold_sq = options.max_error_px * options.max_error_px;
  int count = 0;
  if (mask) mask->assign(observations.size(), 0);
  const PoseProjector projector(pose, options.refine);
  for (size_t i = 0; i < observations.size(); ++i) {
    if (projector.SquaredErrorPx(observations[i]) <= threshold_sq) {
      ++count;
      if (mask) (*mask)[i] = 1;
    }
  }
  return count;
}

std::vector<PoseObservation> Select(const std::vector<PoseObservation>& observations,
                                    const std::vector<char>& mask) {
  std::vector<PoseObservation> selected;
  for (size_t i = 0; i < observations.size(); ++i) {
    if (mask[i]) selected.push_back(observations[i]);
  }
  return selected;
}

// Each camera's inliers under the rig's pose, their masks in `masks` when given.
int CountRigInliers(const Rigid3d& ref_from_world, const RigObservations& rig,
                    const PnpRansacOptions& options, std::vector<std::vector<char>>* masks,
                    std::vector<int>* per_camera = nullptr) {
  int count = 0;
  if (masks) masks->resize(rig.per_camera.size());
  if (per_camera) per_camera->assign(rig.per_camera.size(), 0);
  for (size_t c = 0; c < rig.per_camera.size(); ++c) {
    const int inliers = CountInliers(rig.cam_from_ref[c] * ref_from_world, rig.per_camera[c],
                                     options, masks ? &(*masks)[c] : nullptr);
    if (per_camera) (*per_camera)[c] = inliers;
    count += inliers;
  }
  return count;
}

// Three distinct indices in [0, n), n >= 3.
std::array<int, 3> PickThree(int n, Rng& rng) {
  std::array<int, 3> picks;
  picks[0] = rng.UniformInt(0, n - 1);
  do picks[1] = rng.UniformInt(0, n - 1);
  while (picks[1] == picks[0]);
  do picks[2] = rng.UniformInt(0, n - 1);
  while (picks[2] == picks[0] || picks[2] == picks[1]);
  return picks;
}

// P3P's poses from the three observations `picks`.
std::vector<Rigid3d> SolveSample(const std::vector<PoseObservation>& observations,
                                 const std::array<int, 3>& picks) {
  const std::array<Eigen::Vector3d, 3> points = {observations[picks[0]].point_in_world,
                                                 observations[picks[1]].point_in_world,
                                                 observations[picks[2]].point_in_world};
  const std::array<Eigen::Vector2d, 3> bearings = {observations[picks[0]].normalized,
                                                   observations[picks[1]].normalized,
                                                   observations[picks[2]].normalized};
  return SolveP3P(points, bearings);
}

// Iterations needed to draw one all-inlier sample at `confidence`, when a sample is all
// inliers with probability `all_good`.
int NeededIterations(double all_good, const PnpRansacOptions& options) {
  const int needed = all_good >= 1.0
                         ? options.min_iterations
                         : static_cast<int>(std::ceil(std::log(1 - options.confidence) /
                                                      std::log(std::max(1e-12, 1 - all_good))));
  return std::max(needed, options.min_iterations);
}

}  // namespace

PnpResult SolvePnpRansac(const std::vector<PoseObservation>& observations,
                         const PnpRansacOptions& options) {
  options.Check();
  PnpResult result;
  const int n = static_cast<int>(observations.size());
  if (n < std::max(4, options.min_inliers)) return result;
  Rng rng(options.seed);
  const InlierCounter counter(observations, options.refine);
  int best_inliers = 0;
  Rigid3d best_pose;
  int needed = options.max_iterations;
  int iteration = 0;
  for (; iteration < std::min(needed, options.max_iterations); ++iteration) {
    for (const Rigid3d& candidate : SolveSample(observations, PickThree(n, rng))) {
      const int inliers = counter.Count(candidate, options.max_error_px);
      if (inliers > best_inliers) {
        best_inliers = inliers;
        best_pose = candidate;
        needed = NeededIterations(std::pow(static_cast<double>(inliers) / n, 3), options);
      }
    }
  }
  if (best_inliers < options.min_inliers) {
    result.stats.iterations = iteration;
    return result;
  }
  result = RefinePoseOnInliers(best_pose, observations, options);
  result.stats.iterations = iteration;
  return result;
}

PnpResult RefinePoseOnInliers(const Rigid3d& cam_from_world,
                              const std::vector<PoseObservation>& observations,
                              const PnpRansacOptions& options) {
  PnpResult result;
  const int n = static_cast<int>(observations.size());
  if (n < std::max(3, options.min_inliers)) return result;
  // Select the inliers and refine on them; each further pass re-selects with the refined pose
  // (a rough hypothesis misses inliers at the image edges) and refines again.
  std::vector<char> mask;
  Rigid3d pose = cam_from_world;
  for (int pass = 0; pass < options.refinement_passes; ++pass) {
    if (CountInliers(pose, observations, options, &mask) < options.min_inliers) return result;
    const bool last = pass + 1 == options.refinement_passes;
    pose = RefinePose(pose, Select(observations, mask), options.refine,
                      last ? &result.stats.refine : nullptr, last ? &result.covariance : nullptr);
  }
  result.stats.inliers = CountInliers(pose, observations, options, &result.inlier_mask);
  result.stats.inlier_ratio = static_cast<double>(result.stats.inliers) / n;
  result.cam_from_world = pose;
  result.success = result.stats.inliers >= options.min_inliers;
  return result;
}

RigPnpResult SolveRigPnpRansac(const RigObservations& rig, const PnpRansacOptions& options) {
  options.Check();
  RigPnpResult result;
  const int n = static_cast<int>(rig.size());
  // Cameras that can give a hypothesis, drawn in proportion to their observations.
  std::vector<int> sampled_cameras;
  std::vector<int> cumulative;
  for (size_t c = 0; c < rig.per_camera.size(); ++c) {
    const int count = static_cast<int>(rig.per_camera[c].size());
    if (count < 3) continue;
    sampled_cameras.push_back(static_cast<int>(c));
    cumulative.push_back((cumulative.empty() ? 0 : cumulative.back()) + count);
  }
  if (n < std::max(4, options.min_inliers) || sampled_cameras.empty()) return result;
  Rng rng(options.seed);
  std::vector<InlierCounter> counters;
  for (const auto& observations : rig.per_camera) {
    counters.emplace_back(observations, options.refine);
  }
  // Each sampled camera's best hypothesis by the inliers over all cameras. A hypothesis from
  // three points of one camera can miss the other cameras' points by more than the threshold
  // through the rig's lever arm (a fifth of a degree is 2 px at 160 px of focal length), so the
  // right pose drawn in one camera may count fewer than a wrong one that a narrow view of
  // another allows. Each camera's best is therefore refined on its inliers and counted again
  // (the local optimization of LO-RANSAC, at the end: a pass at twice the threshold, which
  // reaches the other cameras' points, then one at the threshold), and the refined counts
  // decide. Two passes, not more: the tracker re-matches around the winner and refines twice.
  struct Best {
    int inliers = 0;      // The hypothesis's, over all cameras.
    int own_inliers = 0;  // In the camera it was drawn in.
    Rigid3d ref_from_world;
  };
  std::vector<Best> best(rig.per_camera.size());
  std::vector<int> camera_inliers(rig.per_camera.size(), 0);
  PnpRansacOptions local_options = options;
  local_options.refinement_passes = 1;
  PnpRansacOptions wide_options = local_options;
  wide_options.max_error_px = 2 * options.max_error_px;
  int needed = options.max_iterations;
  int iteration = 0;
  for (; iteration < std::min(needed, options.max_iterations); ++iteration) {
    const int draw = rng.UniformInt(0, cumulative.back() - 1);
    const size_t slot =
        std::upper_bound(cumulative.begin(), cumulative.end(), draw) - cumulative.begin();
    const int camera = sampled_cameras[slot];
    const std::vector<PoseObservation>& observations = rig.per_camera[camera];
    const Rigid3d ref_from_cam = rig.cam_from_ref[camera].Inverse();
    const std::array<int, 3> picks = PickThree(static_cast<int>(observations.size()), rng);
    for (const Rigid3d& cam_from_world : SolveSample(observations, picks)) {
      const Rigid3d candidate = ref_from_cam * cam_from_world;
      int inliers = 0;
      for (size_t c = 0; c < counters.size(); ++c) {
        camera_inliers[c] =
            counters[c].Count(rig.cam_from_ref[c] * candidate, options.max_error_px);
        inliers += camera_inliers[c];
      }
      if (inliers <= best[camera].inliers) continue;
      best[camera] = {inliers, camera_inliers[camera], candidate};
      // A draw is all inliers with the chance that its camera's three are: the sum over the
      // sampled cameras of each one's share of the draws times its own inlier share cubed.
      double all_good = 0.0;
      for (const int c : sampled_cameras) {
        const double count = static_cast<double>(rig.per_camera[c].size());
        all_good += count / cumulative.back() * std::pow(best[c].own_inliers / count, 3);
      }
      needed = NeededIterations(all_good, options);
    }
  }
  // The cameras' bests in order of their raw inliers. A camera whose own best hypothesis
  // explains no more of its points than a pose already refined does (from another camera's
  // draw) is not refined again: its refinement would climb the hill the refined pose stands on.
  int local_refinements = 0;
  std::vector<int> order = sampled_cameras;
  std::stable_sort(order.begin(), order.end(),
                   [&](int a, int b) { return best[a].inliers > best[b].inliers; });
  for (const int c : order) {
    if (best[c].inliers < options.min_inliers) continue;
    if (result.success && result.camera_inliers[c] >= best[c].own_inliers) continue;
    ++local_refinements;
    // First at twice the threshold, which takes in the other cameras' points the raw hypothesis
    // misses by a few pixels, then at the threshold (LO-RANSAC's shrinking threshold, Lebeda et
    // al. 2012).
    const RigPnpResult wide = RefineRigPoseOnInliers(best[c].ref_from_world, rig, wide_options);
    RigPnpResult refined = RefineRigPoseOnInliers(
        wide.success ? wide.ref_from_world : best[c].ref_from_world, rig, local_options);
    if (refined.success && (!result.success || refined.stats.inliers > result.stats.inliers)) {
      result = std::move(refined);
    }
  }
  result.stats.iterations = iteration;
  result.stats.local_refinements = local_refinements;
  return result;
}

RigPnpResult RefineRigPoseOnInliers(const Rigid3d& ref_from_world, const RigObservations& rig,
                                    const PnpRansacOptions& options) {
  RigPnpResult result;
  const int n = static_cast<int>(rig.size());
  if (n < std::max(3, options.min_inliers)) return result;
  std::vector<std::vector<char>> masks;
  Rigid3d pose = ref_from_world;
  for (int pass = 0; pass < options.refinement_passes; ++pass) {
    if (CountRigInliers(pose, rig, options, &masks) < options.min_inliers) return result;
    RigObservations selected;
    selected.cam_from_ref = rig.cam_from_ref;
    for (size_t c = 0; c < rig.per_camera.size(); ++c) {
      selected.per_camera.push_back(Select(rig.per_camera[c], masks[c]));
    }
    const bool last = pass + 1 == options.refinement_passes;
    pose = RefineRigPose(pose, selected, options.refine, last ? &result.stats.refine : nullptr,
                         last ? &result.covariance : nullptr);
  }
  result.stats.inliers =
      CountRigInliers(pose, rig, options, &result.inlier_masks, &result.camera_inliers);
  result.stats.inlier_ratio = static_cast<double>(result.stats.inliers) / n;
  result.ref_from_world = pose;
  result.success = result.stats.inliers >= options.min_inliers;
  return result;
}

}  // namespace visloc
