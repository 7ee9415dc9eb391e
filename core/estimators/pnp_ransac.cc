#include "core/estimators/pnp_ransac.h"

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
    int picks[3];
    picks[0] = rng.UniformInt(0, n - 1);
    do picks[1] = rng.UniformInt(0, n - 1);
    while (picks[1] == picks[0]);
    do picks[2] = rng.UniformInt(0, n - 1);
    while (picks[2] == picks[0] || picks[2] == picks[1]);
    const std::array<Eigen::Vector3d, 3> points = {observations[picks[0]].point_in_world,
                                                   observations[picks[1]].point_in_world,
                                                   observations[picks[2]].point_in_world};
    const std::array<Eigen::Vector2d, 3> bearings = {observations[picks[0]].normalized,
                                                     observations[picks[1]].normalized,
                                                     observations[picks[2]].normalized};
    for (const Rigid3d& candidate : SolveP3P(points, bearings)) {
      const int inliers = counter.Count(candidate, options.max_error_px);
      if (inliers > best_inliers) {
        best_inliers = inliers;
        best_pose = candidate;
        const double ratio = static_cast<double>(inliers) / n;
        const double all_good = std::pow(ratio, 3);
        needed = all_good >= 1.0
                     ? options.min_iterations
                     : static_cast<int>(std::ceil(std::log(1 - options.confidence) /
                                                  std::log(std::max(1e-12, 1 - all_good))));
        needed = std::max(needed, options.min_iterations);
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

}  // namespace visloc
