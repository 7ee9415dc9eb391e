#pragma once
// A map arranged for localization: built once when a map is loaded and then shared read-only
// by every session that uses it (it is immutable, so sessions need no locks).
//
// Memory per point, for a map with D-byte descriptors and m observations per point on average:
// 32 B (position + quality) + D (descriptor; 64 B for the paper's 16-float SURF-like descriptor,
// 32 B for ORB) + m * 16 B (observation) + m * 4 B (visibility index): about 176 B per point
// for SURF16 with m = 4. Keyframes add 88 B each plus their appearance vectors.

#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/map/map.h"

namespace visloc {

class LocalizationMap {
 public:
  explicit LocalizationMap(Map map);

  const Map& map() const { return map_; }
  size_t keyframe_count() const { return map_.keyframes.size(); }
  size_t point_count() const { return map_.points.size(); }

  // Indices of the points keyframe `k` sees, ascending (a view into one contiguous array).
  struct PointRange {
    const uint32_t* begin_;
    const uint32_t* end_;
    const uint32_t* begin() const { return begin_; }
    const uint32_t* end() const { return end_; }
    size_t size() const { return static_cast<size_t>(end_ - begin_); }
  };
  PointRange VisiblePoints(size_t keyframe) const;

  // Keyframe camera centres and unit viewing directions (optical axes) in the map frame, the
  // inputs of the visibility kernel's cues.
  const std::vector<Eigen::Vector3d>& keyframe_centers() const { return keyframe_centers_; }
  const std::vector<Eigen::Vector3d>& keyframe_view_dirs() const { return keyframe_view_dirs_; }

  // The appearance index inverted: for each vocabulary word, the keyframes whose vectors hold
  // it, with the keyframe's weight for the word. Empty when the map has no appearance index.
  struct WordEntry {
    uint32_t keyframe;
    float weight;
  };
  const std::vector<std::vector<WordEntry>>& keyframes_by_word() const {
    return keyframes_by_word_;
  }
  // The L1 score (vocabulary.h) of `query` against every keyframe, via the inverted index: for
  // L1-normalized non-negative vectors, 1 - |a - b|_1 / 2 = sum over shared words of min(a, b),
  // so only keyframes that share a word with the query are touched.
  std::vector<float> ScoreKeyframes(const BowVector& query) const;

  // Bytes held, for capacity planning and the memory-per-point figure.
  size_t MemoryBytes() const { return MemoryBytesFor(map_); }
  // The same for a map not (yet) arranged for localization: it follows from the map's sizes.
  static size_t MemoryBytesFor(const Map& map);

 private:
  Map map_;
  std::vector<uint32_t> visible_offsets_;  // keyframe_count + 1 entries (CSR row starts).
  std::vector<uint32_t> visible_points_;
  std::vector<Eigen::Vector3d> keyframe_centers_;
  std::vector<Eigen::Vector3d> keyframe_view_dirs_;
  std::vector<std::vector<WordEntry>> keyframes_by_word_;
};

}  // namespace visloc
