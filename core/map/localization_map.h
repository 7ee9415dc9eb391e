#pragma once
// A map arranged for localization: built once when a map is loaded and then shared read-only
// by every session that uses it (it is immutable, so sessions need no locks).
//
// Memory per point, for a map with D-byte descriptors and m observations per point on average:
// 32 B (position + quality) + D (descriptor; 64 B for the paper's 16-float SURF-like descriptor,
// 32 B for ORB) + m * 16 B (observation) + m * 4 B (visibility index) + 24 B (the point's
// covariance, in maps that record their stereo baseline): about 200 B per point for SURF16
// with m = 4. Keyframes add 88 B each plus their appearance vectors.
//
// A map larger than the memory one wants to give it is paged (the second constructor): the
// keyframes, kernel and appearance index stay resident, and points and visibility lists are read
// per keyframe region on demand through a byte-bounded cache. Point ids are ordered as the
// mapper made them, roughly along the trajectory, so the chunks a frame needs are few.

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "core/map/map.h"
#include "core/map/map_pages.h"
#include "core/map/page_cache.h"
#include "core/map/point_uncertainty.h"

namespace visloc {

// Read access to a map's points by id. For a paged map it pins the chunks holding the ids it
// was made for, so it stays valid, and they stay loaded, while it lives; an id outside that set
// is a CheckError. For a resident map it reads the map itself.
class PointView {
 public:
  const Eigen::Vector3d& position(uint32_t id) const {
    const Block& block = Find(id);
    return block.points[id - block.first].position_in_map;
  }
  // The descriptor matrix holding point `id`, and the point's row in it.
  const cv::Mat& descriptors(uint32_t id, int* row) const {
    const Block& block = Find(id);
    *row = static_cast<int>(id - block.first);
    return *block.descriptors;
  }
  // How well the mapping knows point `id` (point_uncertainty.h); nullptr when the map does not
  // say (a map without its stereo baseline, a paged map).
  const PointCovariance* covariance(uint32_t id) const {
    const Block& block = Find(id);
    return block.covariances ? &block.covariances[id - block.first] : nullptr;
  }
  // The whole map's descriptors, rows = point ids, for a resident map; nullptr for a paged one.
  const cv::Mat* all_descriptors() const { return all_descriptors_; }

 private:
  friend class LocalizationMap;
  struct Block {
    const MapPoint* points = nullptr;
    const cv::Mat* descriptors = nullptr;
    uint32_t first = 0;
    const PointCovariance* covariances = nullptr;
  };
  const Block& Find(uint32_t id) const;

  uint32_t block_points_ = 0xffffffffu;  // Resident: one block holds every point.
  std::vector<Block> blocks_;
  std::vector<std::shared_ptr<const PointChunk>> pins_;
  const cv::Mat* all_descriptors_ = nullptr;
};

class LocalizationMap {
 public:
  // A resident map: everything in memory.
  explicit LocalizationMap(Map map);
  // A paged map: `skeleton` holds everything but the points, descriptors and observations,
  // which `source` provides on demand through a cache of `cache_bytes`.
  LocalizationMap(Map skeleton, std::shared_ptr<const MapPageSource> source, size_t cache_bytes);

  // The map. For a paged map its points, descriptors and observations are empty: read points
  // through Points() and visibility through VisiblePoints().
  const Map& map() const { return map_; }
  size_t keyframe_count() const { return map_.keyframes.size(); }
  size_t point_count() const { return source_ ? source_->point_count() : map_.points.size(); }
  bool paged() const { return source_ != nullptr; }

  // Indices of the points keyframe `k` sees, ascending (for a paged map the list stays loaded
  // while the range lives).
  struct PointRange {
    const uint32_t* begin_;
    const uint32_t* end_;
    std::shared_ptr<const std::vector<uint32_t>> pin_;
    const uint32_t* begin() const { return begin_; }
    const uint32_t* end() const { return end_; }
    size_t size() const { return static_cast<size_t>(end_ - begin_); }
  };
  PointRange VisiblePoints(size_t keyframe) const;

  // The points `ids` (loading the chunks a paged map lacks). Throws InputError when a page
  // does not read.
  PointView Points(const std::vector<uint32_t>& ids) const;
  // Every point: a resident map only (the transparent and brute-force baselines); CheckError
  // for a paged one.
  PointView AllPoints() const;
  // The page cache's counters (all zero for a resident map).
  PageCacheStats page_stats() const;

  // Keyframe camera centres and unit viewing directions (optical axes) in the map frame, the
  // inputs of the visibility kernel's cues.
  const std::vector<Eigen::Vector3d>& keyframe_centers() const { return keyframe_centers_; }
  const std::vector<Eigen::Vector3d>& keyframe_view_dirs() const { return keyframe_view_dirs_; }

  // Whether the map has an appearance index (a vocabulary and keyframe vectors) to score.
  bool has_appearance_index() const { return !postings_.empty(); }
  // The L1 score (vocabulary.h) of `query` against every keyframe, via the inverted index: for
  // L1-normalized non-negative vectors, 1 - |a - b|_1 / 2 = sum over shared words of min(a, b),
  // so only keyframes that share a word with the query are touched.
  std::vector<float> ScoreKeyframes(const BowVector& query) const;

  // Bytes held, for capacity planning and the memory-per-point figure. For a paged map: what
  // stays resident plus the cache's budget.
  size_t MemoryBytes() const;
  // The same for a map not (yet) arranged for localization: it follows from the map's sizes.
  static size_t MemoryBytesFor(const Map& map);
  // What a paged map keeps resident, for the skeleton of `map`: keyframes, kernel, vocabulary
  // and the inverted appearance index (the per-keyframe vectors are dropped once it is built).
  static size_t PagedResidentBytesFor(const Map& skeleton);

 private:
  void BuildPostings();
  Map map_;
  std::vector<uint32_t> visible_offsets_;  // keyframe_count + 1 entries (CSR row starts).
  std::vector<uint32_t> visible_points_;
  std::vector<Eigen::Vector3d> keyframe_centers_;
  std::vector<Eigen::Vector3d> keyframe_view_dirs_;
  // One per point of a resident map that knows its stereo baseline, else empty.
  std::vector<PointCovariance> point_covariances_;
  // The appearance index inverted: for each vocabulary word, the keyframes whose vectors hold it
  // (ascending) with their weights for it. Keyframe ids are stored as 16-bit gaps from the
  // previous one (a gap of 65535 or more as the escape 65535 and the id's two 16-bit halves):
  // 6 bytes an entry instead of 8, with the same scores. For a big map this index is most of
  // what stays resident when it is paged.
  struct PostingList {
    std::vector<uint16_t> gaps;
    std::vector<float> weights;
  };
  static constexpr uint16_t kGapEscape = 0xffff;
  std::vector<PostingList> postings_;
  std::shared_ptr<const MapPageSource> source_;  // Paged maps only.
  std::unique_ptr<PageCache> pages_;
};

}  // namespace visloc
