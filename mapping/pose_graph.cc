#include "mapping/pose_graph.h"

#include <algorithm>
#include <cmath>
#include <unordered_map>

#include <ceres/ceres.h>
#include <ceres/rotation.h>

#include "core/util/check.h"
#include "core/util/timer.h"
#include "mapping/keyframes.h"
#include "mapping/reprojection_cost.h"

namespace visloc::mapping {

void PoseGraphOptions::Check() const {
  VISLOC_CHECK(min_shared_landmarks >= 1 && max_iterations >= 1 && loop_edges_per_keyframe >= 1,
               "pose graph: ", min_shared_landmarks, " shared landmarks, ", max_iterations,
               " iterations, ", loop_edges_per_keyframe, " loop edges per keyframe");
  VISLOC_CHECK(translation_sigma_m > 0 && rotation_sigma_deg > 0, "pose graph sigmas ",
               translation_sigma_m, " m, ", rotation_sigma_deg, " deg");
}

namespace {

// The error of an edge b_from_a: measured^-1 * (T_b T_a^-1), its translation and twice its
// quaternion's vector part (the rotation angle's axis times the angle, to first order), each
// divided by its sigma.
struct RelativePoseCost {
  RelativePoseCost(const Rigid3d& b_from_a, double translation_sigma_m, double rotation_sigma_rad)
      : measured_inverse(b_from_a.Inverse()),
        translation_weight(1.0 / translation_sigma_m),
        rotation_weight(1.0 / rotation_sigma_rad) {}

  template <typename T>
  bool operator()(const T* q_a, const T* t_a, const T* q_b, const T* t_b, T* residuals) const {
    using Quaternion = Eigen::Quaternion<T>;
    using Vector3 = Eigen::Matrix<T, 3, 1>;
    const Eigen::Map<const Quaternion> rotation_a(q_a), rotation_b(q_b);
    const Eigen::Map<const Vector3> translation_a(t_a), translation_b(t_b);
    // T_b T_a^-1 = (R_b R_a^T, t_b - R_b R_a^T t_a).
    const Quaternion rotation_ba = rotation_b * rotation_a.conjugate();
    const Vector3 translation_ba = translation_b - rotation_ba * translation_a;
    const Quaternion measured_rotation = measured_inverse.rotation.cast<T>();
    const Quaternion error_rotation = measured_rotation * rotation_ba;
    const Vector3 error_translation =
        measured_rotation * translation_ba + measured_inverse.translation.cast<T>();
    for (int i = 0; i < 3; ++i) {
      residuals[i] = T(translation_weight) * error_translation[i];
      residuals[3 + i] = T(2.0 * rotation_weight) * error_rotation.vec()[i];
    }
    return true;
  }

  static ceres::CostFunction* Create(const PoseGraphEdge& edge, const PoseGraphOptions& options) {
    return new ceres::AutoDiffCostFunction<RelativePoseCost, 6, 4, 3, 4, 3>(new RelativePoseCost(
        edge.b_from_a, options.translation_sigma_m, options.rotation_sigma_deg * M_PI / 180.0));
  }

  Rigid3d measured_inverse;  // a_from_b as measured.
  double translation_weight, rotation_weight;
};

PoseGraphEdge EdgeNow(const SlamState& state, int a, int b) {
  return {a, b, state.keyframes[b].cam_from_world * state.keyframes[a].cam_from_world.Inverse()};
}

}  // namespace

std::vector<PoseGraphEdge> CovisibilityEdges(const SlamState& state, int anchor, int end,
                                             const PoseGraphOptions& options) {
  options.Check();
  VISLOC_CHECK(end >= 0 && end <= static_cast<int>(state.keyframes.size()) && anchor >= 0,
               "pose graph of ", end, " keyframes of ", state.keyframes.size(), " anchored at ",
               anchor);
  std::vector<PoseGraphEdge> edges;
  for (int k = anchor + 1; k < end; ++k) edges.push_back(EdgeNow(state, k - 1, k));
  // Shared landmarks per pair of keyframes more than one apart, keyed a * end + b (a < b).
  std::unordered_map<int64_t, int> shared;
  std::vector<int> observers;
  for (const Landmark& landmark : state.landmarks) {
    if (landmark.culled) continue;
    observers.clear();
    bool moves = false;  // Seen by a keyframe after the anchor.
    for (const auto& [k, i] : landmark.observations) {
      if (k < end) observers.push_back(k);
      moves |= k > anchor && k < end;
    }
    if (!moves) continue;
    std::sort(observers.begin(), observers.end());
    observers.erase(std::unique(observers.begin(), observers.end()), observers.end());
    for (size_t x = 0; x < observers.size(); ++x) {
      for (size_t y = x + 1; y < observers.size(); ++y) {
        if (observers[y] > observers[x] + 1 && observers[y] > anchor) {
          ++shared[static_cast<int64_t>(observers[x]) * end + observers[y]];
        }
      }
    }
  }
  std::vector<int64_t> strong;
  for (const auto& [pair, count] : shared) {
    if (count >= options.min_shared_landmarks) strong.push_back(pair);
  }
  std::sort(strong.begin(), strong.end());  // Edges in a fixed order: the same map every run.
  for (int64_t pair : strong) {
    edges.push_back(EdgeNow(state, static_cast<int>(pair / end), static_cast<int>(pair % end)));
  }
  return edges;
}

std::vector<PoseGraphEdge> LoopEdges(const SlamState& state, const PoseGraphEdge& closure,
                                     int window, const std::vector<PoseGraphEdge>& edges,
                                     const PoseGraphOptions& options) {
  options.Check();
  const int old = closure.a, current = closure.b;
  VISLOC_CHECK(old >= 0 && old < current && current < static_cast<int>(state.keyframes.size()) &&
                   window >= 1,
               "loop ", old, " -> ", current, " with a window of ", window);
  std::vector<PoseGraphEdge> loop_edges{closure};
  std::vector<int> old_place{old};
  for (const PoseGraphEdge& edge : edges) {
    if (static_cast<int>(old_place.size()) >= options.loop_edges_per_keyframe) break;
    if (edge.a == old && edge.b <= current - window &&
        std::find(old_place.begin(), old_place.end(), edge.b) == old_place.end()) {
      old_place.push_back(edge.b);
    }
  }
  // corrected_w = w_from_current * corrected_current: the window keeps its relative poses.
  const Rigid3d& current_from_world = state.keyframes[current].cam_from_world;
  const Rigid3d corrected_current = closure.b_from_a * state.keyframes[old].cam_from_world;
  for (int w = std::max(old + 1, current - window + 1); w <= current; ++w) {
    const Rigid3d corrected_w =
        state.keyframes[w].cam_from_world * current_from_world.Inverse() * corrected_current;
    for (int o : old_place) {
      if (o >= w || (o == old && w == current)) continue;
      loop_edges.push_back({o, w, corrected_w * state.keyframes[o].cam_from_world.Inverse()});
    }
  }
  return loop_edges;
}

PoseGraphSummary CorrectLoop(const std::vector<PoseGraphEdge>& edges,
                             const std::vector<PoseGraphEdge>& loop_edges,
                             const PoseGraphOptions& options, SlamState* state) {
  options.Check();
  Timer timer;
  VISLOC_CHECK(!loop_edges.empty(), "a loop without its edge");
  const PoseGraphEdge& loop_edge = loop_edges.front();
  const int n = loop_edge.b + 1;
  VISLOC_CHECK(loop_edge.a >= 0 && loop_edge.a < loop_edge.b &&
                   n <= static_cast<int>(state->keyframes.size()),
               "loop edge ", loop_edge.a, " -> ", loop_edge.b);
  for (const PoseGraphEdge& edge : loop_edges) {
    VISLOC_CHECK(edge.a >= 0 && edge.b >= 0 && edge.a < n && edge.b < n, "loop edge ", edge.a,
                 " -> ", edge.b, " beyond keyframe ", loop_edge.b);
  }
  const int anchor = loop_edge.a;  // It and every keyframe before it are held.
  std::vector<PoseBlock> poses(n);
  std::vector<Rigid3d> before(n);
  for (int k = 0; k < n; ++k) {
    before[k] = state->keyframes[k].cam_from_world;
    poses[k] = ToPoseBlock(before[k]);
  }
  ceres::Problem problem;
  PoseGraphSummary summary;
  std::vector<bool> in_problem(n, false);
  auto add_edge = [&](const PoseGraphEdge& edge) {
    if (edge.a >= n || edge.b >= n || std::max(edge.a, edge.b) <= anchor) return;
    problem.AddResidualBlock(RelativePoseCost::Create(edge, options), nullptr, poses[edge.a].data(),
                             poses[edge.a].data() + 4, poses[edge.b].data(),
                             poses[edge.b].data() + 4);
    in_problem[edge.a] = in_problem[edge.b] = true;
    ++summary.edges;
  };
  for (const PoseGraphEdge& edge : edges) add_edge(edge);
  for (const PoseGraphEdge& edge : loop_edges) add_edge(edge);
  for (int k = 0; k < n; ++k) {
    if (in_problem[k]) SetUpPoseBlock(&problem, &poses[k], k <= anchor);
  }
  summary.keyframes = n - anchor - 1;  // That move.
  summary.iterations =
      SolveQuietly(&problem, ceres::SPARSE_NORMAL_CHOLESKY, options.max_iterations);
  // cam_from_world' = corrected_k * before_k^-1 * cam_from_world, for the points each keyframe
  // carries along.
  std::vector<Rigid3d> correction(n);
  for (int k = 0; k < n; ++k) {
    const Rigid3d after = FromPoseBlock(poses[k]);
    correction[k] = after.Inverse() * before[k];  // world' <- world, as seen by keyframe k
    state->keyframes[k].cam_from_world = after;
    summary.max_move_m =
        std::max(summary.max_move_m, (CameraCenter(after) - CameraCenter(before[k])).norm());
  }
  for (Landmark& landmark : state->landmarks) {
    if (landmark.culled || landmark.observations.empty()) continue;
    const int reference = landmark.observations.front().first;
    if (reference < n)
      landmark.position_in_world = correction[reference] * landmark.position_in_world;
  }
  summary.time_ms = timer.ElapsedMs();
  return summary;
}

}  // namespace visloc::mapping
