#include "core/localization/visibility_predictor.h"

#include <algorithm>

#include "core/map/visibility_kernel.h"
#include "core/util/check.h"
#include "core/util/radix_sort.h"

namespace visloc {

void VisibilityOptions::Check() const {
  VISLOC_CHECK(k >= 0, "visibility K ", k);
  VISLOC_CHECK(probability_threshold <= 1.0, "visibility threshold ", probability_threshold);
}

VisibilityPredictor::VisibilityPredictor(const LocalizationMap& map,
                                         const VisibilityOptions& options)
    : map_(map) {
  options.Check();
  const VisibilityKernel& kernel = map.map().kernel;
  VISLOC_CHECK(kernel.metric.rows() == 2 && kernel.cues == KernelCueNames(),
               "the map has no visibility kernel over the cues this visloc uses");
  k_ = options.k > 0 ? options.k : kernel.default_k;
  threshold_ = options.probability_threshold >= 0 ? options.probability_threshold
                                                  : kernel.default_probability_threshold;
  // A dense scratch array per session is 4 bytes per map point: fine for a resident map, not for
  // a paged one of millions of points, which accumulates the few thousand votes by sorting.
  if (!map.paged()) votes_.assign(map.point_count(), 0.0f);
}

std::vector<std::pair<int, double>> VisibilityPredictor::NearestKeyframes(
    const Rigid3d& map_from_cam) const {
  const Eigen::Vector3d center = map_from_cam.translation;
  const Eigen::Vector3d view = map_from_cam.rotation * Eigen::Vector3d::UnitZ();
  const Eigen::MatrixXd& metric = map_.map().kernel.metric;
  std::vector<std::pair<int, double>> scored;
  scored.reserve(map_.keyframe_count());
  for (size_t i = 0; i < map_.keyframe_count(); ++i) {
    const double k = EvaluateKernel(
        metric, KernelCues(center, view, map_.keyframe_centers()[i], map_.keyframe_view_dirs()[i]));
    scored.emplace_back(static_cast<int>(i), k);
  }
  const size_t keep = std::min<size_t>(k_, scored.size());
  std::partial_sort(scored.begin(), scored.begin() + keep, scored.end(),
                    [](const auto& a, const auto& b) { return a.second > b.second; });
  scored.resize(keep);
  return scored;
}

std::vector<PredictedPoint> VisibilityPredictor::Predict(const Rigid3d& map_from_cam,
                                                         VisibilityStats* stats) const {
  const auto nearest = NearestKeyframes(map_from_cam);
  double total = 0.0;
  for (const auto& [keyframe, weight] : nearest) total += weight;
  // (point, summed kernel weight of the nearest keyframes that see it).
  std::vector<std::pair<uint32_t, float>> votes;
  if (!votes_.empty()) {
    for (const auto& [keyframe, weight] : nearest) {
      for (uint32_t point : map_.VisiblePoints(keyframe)) {
        if (votes_[point] == 0.0f) votes.emplace_back(point, 0.0f);
        votes_[point] += static_cast<float>(weight);
      }
    }
    for (auto& [point, vote] : votes) {
      vote = votes_[point];
      votes_[point] = 0.0f;
    }
  } else {
    for (const auto& [keyframe, weight] : nearest) {
      for (uint32_t point : map_.VisiblePoints(keyframe))
        votes.emplace_back(point, static_cast<float>(weight));
    }
    // Stable: each point's votes add up in keyframe order, as in the dense path.
    std::stable_sort(votes.begin(), votes.end(),
                     [](const auto& a, const auto& b) { return a.first < b.first; });
    size_t out = 0;
    for (size_t i = 0; i < votes.size(); ++i) {
      if (out > 0 && votes[out - 1].first == votes[i].first) {
        votes[out - 1].second += votes[i].second;
      } else {
        votes[out++] = votes[i];
      }
    }
    votes.resize(out);
  }
  // Most probable first, ties by point id: radix-sorted keys, several times faster than
  // comparisons for a frame's thousand points. Probabilities are never negative.
  std::vector<uint64_t> order;
  order.reserve(votes.size());
  for (const auto& [point, vote] : votes) {
    const float probability = total > 0 ? static_cast<float>(vote / total) : 0.0f;
    if (probability > threshold_) order.push_back(DescendingKey(probability, point));
  }
  RadixSort(&order);
  std::vector<PredictedPoint> predicted;
  predicted.reserve(order.size());
  for (uint64_t key : order) {
    const uint32_t point = static_cast<uint32_t>(key);
    predicted.push_back({point, DescendingKeyValue(key)});
  }
  if (stats) {
    stats->keyframes_used = static_cast<int>(nearest.size());
    stats->candidates = static_cast<int>(votes.size());
    stats->predicted = static_cast<int>(predicted.size());
  }
  return predicted;
}

std::vector<uint32_t> PredictTransparentWorld(const LocalizationMap& map, const Camera& camera,
                                              const Rigid3d& map_from_cam) {
  const Rigid3d cam_from_map = map_from_cam.Inverse();
  std::vector<uint32_t> visible;
  const PointView points = map.AllPoints();
  for (uint32_t j = 0; j < map.point_count(); ++j) {
    Eigen::Vector2d pixel;
    if (camera.Project(cam_from_map * points.position(j), &pixel) && camera.IsInImage(pixel)) {
      visible.push_back(static_cast<uint32_t>(j));
    }
  }
  return visible;
}

}  // namespace visloc
