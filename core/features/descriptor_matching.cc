#include "core/features/descriptor_matching.h"

#include <cmath>
#include <limits>
#include <optional>

#include "core/features/descriptor.h"
#include "core/util/check.h"

namespace visloc {

KeypointGrid::KeypointGrid(std::vector<Eigen::Vector2f> pixels, int width, int height, int cell_px)
    : pixels_(std::move(pixels)), cell_px_(cell_px) {
  VISLOC_CHECK(cell_px > 0 && width > 0 && height > 0, "grid cell ", cell_px, " image ", width, "x",
               height);
  cols_ = width / cell_px_ + 1;
  rows_ = height / cell_px_ + 1;
  const int n = static_cast<int>(pixels_.size());
  std::vector<int> cell_of(n);
  cell_start_.assign(cols_ * rows_ + 1, 0);
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector2f& p = pixels_[i];
    const int x = std::clamp(static_cast<int>(p.x()) / cell_px_, 0, cols_ - 1);
    const int y = std::clamp(static_cast<int>(p.y()) / cell_px_, 0, rows_ - 1);
    cell_of[i] = y * cols_ + x;
    ++cell_start_[cell_of[i] + 1];
  }
  for (size_t c = 1; c < cell_start_.size(); ++c) cell_start_[c] += cell_start_[c - 1];
  cell_items_.resize(n);
  std::vector<int> fill(cell_start_.begin(), cell_start_.end() - 1);
  for (int i = 0; i < n; ++i) cell_items_[fill[cell_of[i]]++] = i;
}

namespace {

// Guided matching of 16-float descriptors. The keypoints of a row of grid cells are consecutive
// in the grid's cell order (ForEachRunNear); a long run is measured sixteen at a time from the
// descriptors laid out as columns in that order (built on the first long run), a short one
// keypoint by keypoint, those inside the disc only. The disc holds a third of the cells it
// touches at 15 px and 16 px cells (a 320x240 query) and two thirds at 58 px (a KITTI-wide map
// build's search), so only wide searches make runs worth a vector.
class GuidedFloat16 {
 public:
  GuidedFloat16(const KeypointGrid& grid, const cv::Mat& descriptors)
      : grid_(grid), descriptors_(descriptors) {}

  // Offers `query` the keypoints within `radius_px` of its prediction in ForEachWithin's order,
  // each at its squared distance, and leaves `nearest` with the roots: as offering
  // DescriptorDistance itself would (Float16Columns::Nearest says why squares choose the same).
  NearestTwo Nearest(const GuidedQuery& query, double radius_px) {
    const float* row = query.descriptors->ptr<float>(query.row);
    const std::vector<int>& order = grid_.cell_order();
    NearestTwo nearest;
    grid_.ForEachRunNear(query.pixel, radius_px, [&](int begin, int end) {
      if (end - begin < kLongRun) {
        for (int j = begin; j < end; ++j) {
          const int i = order[j];
          if (grid_.Within(i, query.pixel, radius_px)) {
            nearest.Offer(SquaredDistance16(row, descriptors_.ptr<float>(i)), i);
          }
        }
        return;
      }
      if (!columns_)
        columns_.emplace(descriptors_, std::vector<uint32_t>(order.begin(), order.end()));
      squared_.resize(end - begin + 15);  // Float16Columns::SquaredDistances stores vectors.
      columns_->SquaredDistances(row, begin, end - begin, squared_.data());
      for (int j = begin; j < end; ++j) {
        if (grid_.Within(order[j], query.pixel, radius_px)) {
          nearest.Offer(squared_[j - begin], order[j]);
        }
      }
    });
    constexpr float kNone = std::numeric_limits<float>::max();
    if (nearest.best < kNone) nearest.best = std::sqrt(nearest.best);
    if (nearest.second < kNone) nearest.second = std::sqrt(nearest.second);
    return nearest;
  }

 private:
  static constexpr int kLongRun = 16;  // A vector's worth.
  const KeypointGrid& grid_;
  const cv::Mat& descriptors_;
  std::optional<Float16Columns> columns_;
  std::vector<float> squared_;
};

constexpr int kPrefetchAhead = 4;

}  // namespace

std::vector<GuidedMatch> MatchGuided(const std::vector<GuidedQuery>& queries,
                                     const KeypointGrid& grid, const cv::Mat& keypoint_descriptors,
                                     double radius_px, const DescriptorMatchOptions& options) {
  const float max_distance = options.MaxDistance(
      keypoint_descriptors.type() == CV_8U ? DescriptorType::kBinary : DescriptorType::kFloat32);
  if (grid.size() == 0) return {};
  // Per keypoint, the closest query that claimed it.
  std::vector<GuidedMatch> claims(grid.size(), {-1, 0, std::numeric_limits<float>::max()});
  const bool float16 = keypoint_descriptors.type() == CV_32F && keypoint_descriptors.cols == 16;
  GuidedFloat16 guided(grid, keypoint_descriptors);
  const int count = static_cast<int>(queries.size());
  for (int q = 0; q < count; ++q) {
    const GuidedQuery& query = queries[q];
    // The queries' descriptors are map points' rows, scattered over a map's matrix: fetching a
    // few queries ahead hides the cache misses that were a fifth of a tracking frame's matching.
    if (q + kPrefetchAhead < count) {
      const GuidedQuery& ahead = queries[q + kPrefetchAhead];
      __builtin_prefetch(ahead.descriptors->ptr(ahead.row));
    }
    VISLOC_CHECK(query.descriptors->type() == keypoint_descriptors.type() &&
                     query.descriptors->cols == keypoint_descriptors.cols,
                 "guided matching: query and keypoint descriptors differ in type or width");
    NearestTwo nearest;
    if (float16) {
      nearest = guided.Nearest(query, radius_px);
    } else {
      grid.ForEachWithin(query.pixel, radius_px, [&](int i) {
        nearest.Offer(DescriptorDistance(*query.descriptors, query.row, keypoint_descriptors, i),
                      i);
      });
    }
    if (!nearest.Distinctive(options.ratio, max_distance)) continue;
    GuidedMatch& claim = claims[nearest.best_index];
    if (nearest.best < claim.distance) claim = {q, nearest.best_index, nearest.best};
  }
  std::vector<GuidedMatch> matches;
  for (const GuidedMatch& claim : claims) {
    if (claim.query >= 0) matches.push_back(claim);
  }
  return matches;
}

std::vector<std::pair<int, int>> MatchMutualNearest(const cv::Mat& a, const cv::Mat& b,
                                                    const DescriptorMatchOptions& options) {
  if (a.empty() || b.empty()) return {};
  VISLOC_CHECK(a.type() == b.type() && a.cols == b.cols, "descriptor sets differ in type or width");
  const float max_distance =
      options.MaxDistance(a.type() == CV_8U ? DescriptorType::kBinary : DescriptorType::kFloat32);
  std::vector<NearestTwo> from_a(a.rows), from_b(b.rows);
  for (int i = 0; i < a.rows; ++i) {
    for (int j = 0; j < b.rows; ++j) {
      const float distance = DescriptorDistance(a, i, b, j);
      from_a[i].Offer(distance, j);
      from_b[j].Offer(distance, i);
    }
  }
  std::vector<std::pair<int, int>> pairs;
  for (int i = 0; i < a.rows; ++i) {
    const int j = from_a[i].best_index;
    if (!from_a[i].Distinctive(options.ratio, max_distance)) continue;
    if (from_b[j].best_index == i && from_b[j].Distinctive(options.ratio, max_distance)) {
      pairs.emplace_back(i, j);
    }
  }
  return pairs;
}

}  // namespace visloc
