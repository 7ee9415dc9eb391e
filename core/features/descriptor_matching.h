#pragma once
// Descriptor matching shared by mapping and localization.
//
// Guided (MatchGuided), the one matcher tracking uses in both: scene points whose image position
// is predicted (projected with a prior pose) are matched to the keypoints within a search radius
// of the prediction (seed paper 000, sec. 5). A match must pass DescriptorMatchOptions (distance
// and ratio test), and each keypoint keeps only the closest point that claims it.
//
// Unguided (MatchMutualNearest): two descriptor sets with no geometry at all, for checks that
// must not assume what they measure (a rig's calibration).

#include <algorithm>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "core/features/feature_types.h"

namespace visloc {

// Keypoint positions bucketed in square cells, for radius searches.
class KeypointGrid {
 public:
  KeypointGrid() = default;
  // `pixels` in an image of `width` x `height`; positions outside it go to the border cells.
  KeypointGrid(std::vector<Eigen::Vector2f> pixels, int width, int height, int cell_px);

  size_t size() const { return pixels_.size(); }
  const Eigen::Vector2f& pixel(int i) const { return pixels_[i]; }

  // Calls visit(i) for every keypoint within `radius_px` of `center_px`, in cell order (cells
  // row by row, a cell's keypoints by index).
  template <typename Visit>
  void ForEachWithin(const Eigen::Vector2d& center_px, double radius_px, Visit&& visit) const;

  // The keypoints in cell order: keypoint cell_order()[j] is the j-th.
  const std::vector<int>& cell_order() const { return cell_items_; }
  // Calls visit(begin, end) for each row of cells the disc of `radius_px` around `center_px`
  // touches: the keypoints of that row's cells under the disc are positions [begin, end) of
  // cell_order(), consecutive. They include keypoints outside the disc (Within tells).
  template <typename VisitRun>
  void ForEachRunNear(const Eigen::Vector2d& center_px, double radius_px, VisitRun&& visit) const;
  // Whether keypoint i lies within `radius_px` of `center_px` (ForEachWithin's test).
  bool Within(int i, const Eigen::Vector2d& center_px, double radius_px) const {
    const float dx = pixels_[i].x() - static_cast<float>(center_px.x());
    const float dy = pixels_[i].y() - static_cast<float>(center_px.y());
    return dx * dx + dy * dy <= static_cast<float>(radius_px * radius_px);
  }

 private:
  std::vector<Eigen::Vector2f> pixels_;
  int cell_px_ = 1;
  int cols_ = 0;
  int rows_ = 0;
  std::vector<int> cell_start_;  // CSR over cells (cols_ * rows_ + 1 entries).
  std::vector<int> cell_items_;
};

// A scene point to find: its descriptor (row `row` of `descriptors`) and where it should be.
struct GuidedQuery {
  const cv::Mat* descriptors = nullptr;
  int row = 0;
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();
};

struct GuidedMatch {
  int query = 0;     // Index into the queries.
  int keypoint = 0;  // Index into the grid's keypoints (and rows of their descriptors).
  float distance = 0.0f;
};

// Matches each query to the nearest keypoint (in descriptor space) within `radius_px` of its
// predicted pixel. Results are ordered by keypoint. Query and keypoint descriptors must be of
// the same type and width.
std::vector<GuidedMatch> MatchGuided(const std::vector<GuidedQuery>& queries,
                                     const KeypointGrid& grid, const cv::Mat& keypoint_descriptors,
                                     double radius_px, const DescriptorMatchOptions& options);

// Pairs (a, b) of rows of `a` and `b` that are each other's nearest neighbour and pass
// DescriptorMatchOptions in both directions. Brute force: for diagnostics, not per-frame work.
std::vector<std::pair<int, int>> MatchMutualNearest(const cv::Mat& a, const cv::Mat& b,
                                                    const DescriptorMatchOptions& options);

template <typename VisitRun>
void KeypointGrid::ForEachRunNear(const Eigen::Vector2d& center_px, double radius_px,
                                  VisitRun&& visit) const {
  if (cols_ == 0) return;
  const int x0 = std::max(0, static_cast<int>((center_px.x() - radius_px) / cell_px_));
  const int x1 = std::min(cols_ - 1, static_cast<int>((center_px.x() + radius_px) / cell_px_));
  const int y0 = std::max(0, static_cast<int>((center_px.y() - radius_px) / cell_px_));
  const int y1 = std::min(rows_ - 1, static_cast<int>((center_px.y() + radius_px) / cell_px_));
  for (int y = y0; y <= y1 && x0 <= x1; ++y) {
    const int begin = cell_start_[y * cols_ + x0], end = cell_start_[y * cols_ + x1 + 1];
    if (begin < end) visit(begin, end);
  }
}

template <typename Visit>
void KeypointGrid::ForEachWithin(const Eigen::Vector2d& center_px, double radius_px,
                                 Visit&& visit) const {
  ForEachRunNear(center_px, radius_px, [&](int begin, int end) {
    for (int j = begin; j < end; ++j) {
      if (Within(cell_items_[j], center_px, radius_px)) visit(cell_items_[j]);
    }
  });
}

}  // namespace visloc
