#pragma once
// Where a paged map's bulk comes from. A map too large to hold whole keeps its keyframes, kernel
// and appearance index resident and reads its points (in chunks of consecutive ids) and its
// keyframes' visibility lists on demand, through this interface; mapstore implements it over
// the map file, so the core knows nothing of SQLite.

#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>

#include "core/map/map.h"

namespace visloc {

// Points [first, first + points.size()) of a map, with their descriptors (one row each).
struct PointChunk {
  uint32_t first = 0;
  std::vector<MapPoint> points;
  cv::Mat descriptors;
  size_t Bytes() const {
    return sizeof(*this) + points.size() * sizeof(MapPoint) +
           descriptors.total() * descriptors.elemSize();
  }
};

class MapPageSource {
 public:
  virtual ~MapPageSource() = default;
  virtual uint32_t point_count() const = 0;
  // Points per chunk: chunk c holds points [c * chunk_points, ...). Every chunk but the last is
  // full.
  virtual uint32_t chunk_points() const = 0;
  // Both thread-safe; throw InputError naming the file and the part that does not read.
  virtual PointChunk LoadPointChunk(uint32_t chunk) const = 0;
  // The ids of the points keyframe `keyframe` observes, ascending.
  virtual std::vector<uint32_t> LoadVisiblePoints(uint32_t keyframe) const = 0;
  // Bytes the whole bulk would take in memory (points, descriptors, visibility lists).
  virtual size_t BulkBytes() const = 0;
};

}  // namespace visloc
