#include "core/map/localization_map.h"

#include <algorithm>

#include "core/util/check.h"

namespace visloc {

namespace {

// Page keys: point chunks and visibility lists share one cache.
constexpr uint64_t kVisibilityPage = uint64_t{1} << 40;

}  // namespace

const PointView::Block& PointView::Find(uint32_t id) const {
  const size_t b = id / block_points_;
  VISLOC_CHECK(b < blocks_.size() && blocks_[b].points != nullptr, "point ", id,
               " is not in this view");
  return blocks_[b];
}

LocalizationMap::LocalizationMap(Map skeleton, std::shared_ptr<const MapPageSource> source,
                                 size_t cache_bytes)
    : LocalizationMap(std::move(skeleton)) {
  VISLOC_CHECK(source != nullptr && source->chunk_points() > 0, "a paged map needs its pages");
  VISLOC_CHECK(map_.points.empty() && map_.observations.empty(),
               "a paged map's skeleton holds no points");
  source_ = std::move(source);
  pages_ = std::make_unique<PageCache>(cache_bytes);
  // Scoring reads the inverted index only; the vectors it was built from would double it.
  map_.appearance.keyframe_vectors.clear();
  map_.appearance.keyframe_vectors.shrink_to_fit();
}

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
    // Counted first, so each word's list is allocated once at its size (growing by doubling
    // would leave up to half of a big map's index unused).
    std::vector<size_t> entries(keyframes_by_word_.size(), 0);
    for (const BowVector& v : appearance.keyframe_vectors) {
      for (const auto& [word, weight] : v) {
        if (word < entries.size()) ++entries[word];
      }
    }
    for (size_t w = 0; w < entries.size(); ++w) keyframes_by_word_[w].reserve(entries[w]);
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
  if (!source_) {
    const uint32_t* base = visible_points_.data();
    return {base + visible_offsets_[keyframe], base + visible_offsets_[keyframe + 1], nullptr};
  }
  auto list = std::static_pointer_cast<const std::vector<uint32_t>>(
      pages_->Get(kVisibilityPage + keyframe, [&](size_t* bytes) {
        auto loaded = std::make_shared<const std::vector<uint32_t>>(
            source_->LoadVisiblePoints(static_cast<uint32_t>(keyframe)));
        *bytes = sizeof(*loaded) + loaded->size() * sizeof(uint32_t);
        return std::shared_ptr<const void>(loaded);
      }));
  return {list->data(), list->data() + list->size(), list};
}

PointView LocalizationMap::AllPoints() const {
  VISLOC_CHECK(!source_, "a paged map does not hold all its points at once: the transparent and "
                         "brute-force baselines need a resident map");
  PointView view;
  view.blocks_ = {{map_.points.data(), &map_.descriptors, 0}};
  view.all_descriptors_ = &map_.descriptors;
  return view;
}

PointView LocalizationMap::Points(const std::vector<uint32_t>& ids) const {
  if (!source_) return AllPoints();
  PointView view;
  const uint32_t per_chunk = source_->chunk_points();
  view.block_points_ = per_chunk;
  view.blocks_.resize((source_->point_count() + per_chunk - 1) / per_chunk);
  for (uint32_t id : ids) {
    const uint32_t c = id / per_chunk;
    VISLOC_CHECK(c < view.blocks_.size(), "point ", id, " of ", source_->point_count());
    if (view.blocks_[c].points != nullptr) continue;
    auto chunk = std::static_pointer_cast<const PointChunk>(pages_->Get(c, [&](size_t* bytes) {
      auto loaded = std::make_shared<const PointChunk>(source_->LoadPointChunk(c));
      *bytes = loaded->Bytes();
      return std::shared_ptr<const void>(loaded);
    }));
    view.blocks_[c] = {chunk->points.data(), &chunk->descriptors, chunk->first};
    view.pins_.push_back(std::move(chunk));
  }
  return view;
}

PageCacheStats LocalizationMap::page_stats() const { return pages_ ? pages_->stats() : PageCacheStats{}; }

size_t LocalizationMap::MemoryBytes() const {
  if (!source_) return MemoryBytesFor(map_);
  size_t index_entries = 0;
  for (const auto& entries : keyframes_by_word_) index_entries += entries.size();
  return MemoryBytesFor(map_) + index_entries * sizeof(WordEntry) + page_stats().budget_bytes;
}

size_t LocalizationMap::PagedResidentBytesFor(const Map& skeleton) {
  size_t vector_entries = 0;
  for (const BowVector& v : skeleton.appearance.keyframe_vectors) vector_entries += v.size();
  // MemoryBytesFor counts each entry in the vectors and in the index.
  return MemoryBytesFor(skeleton) - vector_entries * sizeof(BowVector::value_type);
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
