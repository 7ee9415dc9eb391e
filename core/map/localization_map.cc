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
  if (const auto baseline_m = map_.metadata.stereo_baseline_m; baseline_m && !map_.points.empty()) {
    point_covariances_ = PointCovariances(map_, *baseline_m);
  }
  BuildPostings();
}

void LocalizationMap::BuildPostings() {
  const AppearanceIndex& appearance = map_.appearance;
  if (appearance.keyframe_vectors.empty()) return;
  postings_.resize(appearance.vocabulary.word_count());
  // Counted first, so each word's list is allocated once at its size (growing by doubling
  // would leave up to half of a big map's index unused).
  std::vector<size_t> entries(postings_.size(), 0);
  for (const BowVector& v : appearance.keyframe_vectors) {
    for (const auto& [word, weight] : v) {
      if (word < entries.size()) ++entries[word];
    }
  }
  for (size_t w = 0; w < entries.size(); ++w) {
    postings_[w].gaps.reserve(entries[w]);
    postings_[w].weights.reserve(entries[w]);
  }
  std::vector<uint32_t> last(postings_.size(), 0);
  for (size_t k = 0; k < appearance.keyframe_vectors.size(); ++k) {
    const auto keyframe = static_cast<uint32_t>(k);
    for (const auto& [word, weight] : appearance.keyframe_vectors[k]) {
      VISLOC_CHECK(word < postings_.size(), "keyframe ", k, " has word ", word, " of ",
                   postings_.size());
      PostingList& list = postings_[word];
      const uint32_t gap = keyframe - last[word];
      if (gap < kGapEscape) {
        list.gaps.push_back(static_cast<uint16_t>(gap));
      } else {
        list.gaps.insert(list.gaps.end(), {kGapEscape, static_cast<uint16_t>(keyframe >> 16),
                                           static_cast<uint16_t>(keyframe & 0xffff)});
      }
      list.weights.push_back(weight);
      last[word] = keyframe;
    }
  }
}

std::vector<float> LocalizationMap::ScoreKeyframes(const BowVector& query) const {
  std::vector<float> scores(keyframe_count(), 0.0f);
  for (const auto& [word, weight] : query) {
    if (word >= postings_.size()) continue;
    const PostingList& list = postings_[word];
    uint32_t keyframe = 0;
    size_t g = 0;
    for (float keyframe_weight : list.weights) {
      const uint16_t gap = list.gaps[g++];
      if (gap == kGapEscape) {
        keyframe = (static_cast<uint32_t>(list.gaps[g]) << 16) | list.gaps[g + 1];
        g += 2;
      } else {
        keyframe += gap;
      }
      scores[keyframe] += std::min(weight, keyframe_weight);
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
  VISLOC_CHECK(!source_,
               "a paged map does not hold all its points at once: the transparent and "
               "brute-force baselines need a resident map");
  PointView view;
  view.blocks_ = {{map_.points.data(), &map_.descriptors, 0,
                   point_covariances_.empty() ? nullptr : point_covariances_.data()}};
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

PageCacheStats LocalizationMap::page_stats() const {
  return pages_ ? pages_->stats() : PageCacheStats{};
}

size_t LocalizationMap::MemoryBytes() const {
  if (!source_) return MemoryBytesFor(map_);
  size_t index_bytes = 0;
  for (const PostingList& list : postings_) {
    index_bytes += list.gaps.size() * sizeof(uint16_t) + list.weights.size() * sizeof(float);
  }
  return MemoryBytesFor(map_) + index_bytes + page_stats().budget_bytes;
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
  // The points' covariances, for a map that knows its baseline (point_uncertainty.h).
  if (map.metadata.stereo_baseline_m) bytes += map.points.size() * sizeof(PointCovariance);
  const AppearanceIndex& appearance = map.appearance;
  bytes += appearance.vocabulary.centroids.total() * appearance.vocabulary.centroids.elemSize() +
           appearance.vocabulary.word_weights.size() * sizeof(float);
  for (const BowVector& v : appearance.keyframe_vectors) {
    // The vector, plus its entries in the inverted index (a 16-bit gap and a weight).
    bytes += v.size() * (sizeof(v[0]) + sizeof(uint16_t) + sizeof(float));
  }
  bytes += appearance.vocabulary.word_weights.size() * sizeof(PostingList);
  return bytes;
}

}  // namespace visloc
