#include "core/map/localization_map.h"

#include <algorithm>

#include "core/util/check.h"

namespace visloc {

LocalizationMap::LocalizationMap(Map map) : map_(std::move(map)) {
  const auto problems = FindMapProblems(map_, 1);
  VISLOC_CHECK(problems.empty(), "inconsistent map: ", problems.empty() ? "" : problems[0]);
  // Observations are sorted by (keyframe, point), so the CSR arrays fill in one pass.
  visible_offsets_.assign(map_.keyframes.size() + 1, 0);
  visible_points_.reserve(map_.observations.size());
  for (const Observation& o : map_.observations) {
    ++visible_offsets_[o.keyframe + 1];
    visible_points_.push_back(o.point);
  }
  for (size_t k = 1; k < visible_offsets_.size(); ++k)
    visible_offsets_[k] += visible_offsets_[k - 1];
  for (const Keyframe& keyframe : map_.keyframes) {
    keyframe_centers_.push_back(keyframe.map_from_cam.translation);
    keyframe_view_dirs_.push_back(keyframe.map_from_cam.rotation * Eigen::Vector3d::UnitZ());
  }
  const AppearanceIndex& appearance = map_.appearance;
  if (!appearance.keyframe_vectors.empty()) {
    keyframes_by_word_.resize(appearance.vocabulary.word_count());
    for (size_t k = 0; k < appearance.keyframe_vectors.size(); ++k) {
      for (const auto& [word, weight] : appearance.keyframe_vectors[k]) {
        VISLOC_CHECK(word < keyframes_by_word_.size(), "keyframe ", k, " has word ", word, " of ",
                     keyframes_by_word_.size());
        keyframes_by_word_[word].push_back({static_cast<uint32_t>(k), weight});
      }
    }
  }
}

std::vector<float> LocalizationMap::ScoreKeyframes(const BowVector& query) const {
  std::vector<float> scores(keyframe_count(), 0.0f);
  for (const auto& [word, weight] : query) {
    if (word >= keyframes_by_word_.size()) continue;
    for (const WordEntry& entry : keyframes_by_word_[word]) {
      scores[entry.keyframe] += std::min(weight, entry.weight);
    }
  }
  return scores;
}

LocalizationMap::PointRange LocalizationMap::VisiblePoints(size_t keyframe) const {
  VISLOC_CHECK(keyframe < keyframe_count(), "keyframe ", keyframe, " of ", keyframe_count());
  const uint32_t* base = visible_points_.data();
  return {base + visible_offsets_[keyframe], base + visible_offsets_[keyframe + 1]};
}

size_t LocalizationMap::MemoryBytesFor(const Map& map) {
  size_t bytes = map.keyframes.size() * sizeof(Keyframe) + map.points.size() * sizeof(MapPoint) +
                 map.descriptors.total() * map.descriptors.elemSize() +
                 map.observations.size() * sizeof(Observation) +
                 // CSR visibility: offsets per keyframe + one index per observation.
                 (map.keyframes.size() + 1 + map.observations.size()) * sizeof(uint32_t) +
                 // Keyframe centres and viewing directions.
                 2 * map.keyframes.size() * sizeof(Eigen::Vector3d);
  const AppearanceIndex& appearance = map.appearance;
  bytes += appearance.vocabulary.centroids.total() * appearance.vocabulary.centroids.elemSize() +
           appearance.vocabulary.word_weights.size() * sizeof(float);
  for (const BowVector& v : appearance.keyframe_vectors) {
    bytes += v.size() * (sizeof(v[0]) + sizeof(WordEntry));  // Vector plus inverted index.
  }
  bytes += appearance.vocabulary.word_weights.size() * sizeof(std::vector<WordEntry>);
  return bytes;
}

}  // namespace visloc
