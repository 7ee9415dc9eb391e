#include "core/localization/visibility_predictor.h"

#include <algorithm>

#include "core/map/visibility_kernel.h"
#include "core/util/check.h"

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
  votes_.assign(map.point_count(), 0.0f);
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
  std::vector<uint32_t> touched;
  for (const auto& [keyframe, weight] : nearest) {
    total += weight;
    for (uint32_t point : map_.VisiblePoints(keyframe)) {
      if (votes_[point] == 0.0f) touched.push_back(point);
      votes_[point] += static_cast<float>(weight);
    }
  }
  std::vector<PredictedPoint> predicted;
  for (uint32_t point : touched) {
    const float probability = total > 0 ? static_cast<float>(votes_[point] / total) : 0.0f;
    if (probability > threshold_) predicted.push_back({point, probability});
    votes_[point] = 0.0f;
  }
  std::sort(predicted.begin(), predicted.end(),
            [](const PredictedPoint& a, const PredictedPoint& b) {
              return a.probability > b.probability ||
                     (a.probability == b.probability && a.point < b.point);
            });
  if (stats) {
    stats->keyframes_used = static_cast<int>(nearest.size());
    stats->candidates = static_cast<int>(touched.size());
    stats->predicted = static_cast<int>(predicted.size());
  }
  return predicted;
}

std::vector<uint32_t> PredictTransparentWorld(const LocalizationMap& map,
                                              const Camera& camera,
                                              const Rigid3d& map_from_cam) {
  const Rigid3d cam_from_map = map_from_cam.Inverse();
  std::vector<uint32_t> visible;
  const PointView points = map.AllPoints();
  for (uint32_t j = 0; j < map.point_count(); ++j) {
    Eigen::Vector2d pixel;
    if (camera.Project(cam_from_map * points.position(j), &pixel) &&
        camera.IsInImage(pixel)) {
      visible.push_back(static_cast<uint32_t>(j));
    }
  }
  return visible;
}

}  // namespace visloc
