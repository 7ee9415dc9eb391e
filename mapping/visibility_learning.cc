#include "mapping/visibility_learning.h"

#include <ceres/ceres.h>

#include <algorithm>
#include <cmath>

#include "core/map/localization_map.h"
#include "core/map/visibility_kernel.h"

namespace visloc::mapping {
namespace {

// Residual k(A d) - y for one keyframe pair. Parameter: A row-major (4).
struct KernelFitCost {
  KernelFitCost(const Eigen::Vector2d& cues, double target) : cues(cues), target(target) {}
  template <typename T>
  bool operator()(const T* a, T* residual) const {
    const T x = a[0] * T(cues.x()) + a[1] * T(cues.y());
    const T y = a[2] * T(cues.x()) + a[3] * T(cues.y());
    // sqrt is not differentiable at 0; cues of distinct keyframes are never both zero.
    residual[0] = exp(-sqrt(x * x + y * y + T(1e-12))) - T(target);
    return true;
  }
  Eigen::Vector2d cues;
  double target;
};

}  // namespace

Eigen::MatrixXd VisibilityOverlap(const Map& map) {
  const int n = static_cast<int>(map.keyframes.size());
  std::vector<std::vector<uint32_t>> visible(n);
  for (const Observation& o : map.observations) visible[o.keyframe].push_back(o.point);
  Eigen::MatrixXd overlap = Eigen::MatrixXd::Identity(n, n);
  for (int i = 0; i < n; ++i) {
    for (int j = i + 1; j < n; ++j) {
      if (visible[i].empty() || visible[j].empty()) continue;
      std::vector<uint32_t> common;
      std::set_intersection(visible[i].begin(), visible[i].end(), visible[j].begin(),
                            visible[j].end(), std::back_inserter(common));
      const double y = 0.5 * (static_cast<double>(common.size()) / visible[i].size() +
                              static_cast<double>(common.size()) / visible[j].size());
      overlap(i, j) = overlap(j, i) = y;
    }
  }
  return overlap;
}

VisibilityKernel LearnVisibilityKernel(const Map& map, const VisibilityLearningOptions& options,
                                       VisibilityLearningStats* stats) {
  VisibilityKernel kernel;
  kernel.cues = KernelCueNames();
  kernel.default_k = options.default_k;
  kernel.default_probability_threshold = options.default_probability_threshold;
  const int n = static_cast<int>(map.keyframes.size());
  std::vector<Eigen::Vector3d> centers, views;
  for (const Keyframe& k : map.keyframes) {
    centers.push_back(k.map_from_cam.translation);
    views.push_back(k.map_from_cam.rotation * Eigen::Vector3d::UnitZ());
  }
  const Eigen::MatrixXd overlap = VisibilityOverlap(map);
  std::vector<std::pair<Eigen::Vector2d, double>> pairs;
  const long total_pairs = static_cast<long>(n) * (n - 1) / 2;
  const long stride = std::max(1L, total_pairs / options.max_pairs);
  long index = 0;
  for (int i = 0; i < n; ++i) {
    for (int j = i + 1; j < n; ++j, ++index) {
      if (index % stride == 0)
        pairs.emplace_back(KernelCues(centers[i], views[i], centers[j], views[j]), overlap(i, j));
    }
  }
  double a[4] = {3.0, 0.0, 0.0, 3.0};  // Initial metric: overlap halves at ~0.2 m or ~35 deg.
  auto rmse = [&](const double* metric) {
    double sum = 0;
    for (const auto& [cues, y] : pairs) {
      const Eigen::Vector2d v(metric[0] * cues.x() + metric[1] * cues.y(),
                              metric[2] * cues.x() + metric[3] * cues.y());
      sum += std::pow(std::exp(-v.norm()) - y, 2);
    }
    return pairs.empty() ? 0.0 : std::sqrt(sum / pairs.size());
  };
  VisibilityLearningStats local;
  local.pairs = static_cast<int>(pairs.size());
  local.initial_rmse = rmse(a);
  if (!pairs.empty()) {
    ceres::Problem problem;
    for (const auto& [cues, y] : pairs) {
      problem.AddResidualBlock(
          new ceres::AutoDiffCostFunction<KernelFitCost, 1, 4>(new KernelFitCost(cues, y)), nullptr,
          a);
    }
    ceres::Solver::Options solver_options;
    solver_options.max_num_iterations = 100;
    solver_options.logging_type = ceres::SILENT;
    ceres::Solver::Summary summary;
    ceres::Solve(solver_options, &problem, &summary);
  }
  local.final_rmse = rmse(a);
  kernel.metric.resize(2, 2);
  kernel.metric << a[0], a[1], a[2], a[3];
  if (stats) *stats = local;
  return kernel;
}

}  // namespace visloc::mapping
