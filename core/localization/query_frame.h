#pragma once
// One query image's features, prepared for matching: keypoints in raw (distorted) pixels, their
// undistorted normalized coordinates for the pose solvers, and a grid over the image for radius
// searches around projected map points.

#include <vector>

#include <Eigen/Core>

#include "core/camera/pinhole_camera.h"
#include "core/features/features.h"

namespace visloc {

class QueryFrame {
 public:
  // `cell_px` is the grid's cell size; radius searches look at the cells a disc touches.
  QueryFrame(FeatureSet features, const PinholeCamera& camera, int cell_px = 16);

  const FeatureSet& features() const { return features_; }
  size_t size() const { return features_.size(); }
  // Undistorted normalized image coordinates (x/z, y/z) of keypoint i.
  const Eigen::Vector2d& normalized(int i) const { return normalized_[i]; }

  // Calls visit(i) for every keypoint within `radius_px` of `center_px`.
  template <typename Visit>
  void ForEachWithin(const Eigen::Vector2d& center_px, double radius_px, Visit&& visit) const;

 private:
  FeatureSet features_;
  std::vector<Eigen::Vector2d> normalized_;
  int cell_px_;
  int cols_ = 0;
  int rows_ = 0;
  std::vector<int> cell_start_;  // CSR over cells (cols_ * rows_ + 1 entries).
  std::vector<int> cell_items_;
};

template <typename Visit>
void QueryFrame::ForEachWithin(const Eigen::Vector2d& center_px, double radius_px,
                               Visit&& visit) const {
  const int x0 = std::max(0, static_cast<int>((center_px.x() - radius_px) / cell_px_));
  const int x1 = std::min(cols_ - 1, static_cast<int>((center_px.x() + radius_px) / cell_px_));
  const int y0 = std::max(0, static_cast<int>((center_px.y() - radius_px) / cell_px_));
  const int y1 = std::min(rows_ - 1, static_cast<int>((center_px.y() + radius_px) / cell_px_));
  const float cx = static_cast<float>(center_px.x()), cy = static_cast<float>(center_px.y());
  const float r2 = static_cast<float>(radius_px * radius_px);
  for (int y = y0; y <= y1; ++y) {
    for (int x = x0; x <= x1; ++x) {
      const int cell = y * cols_ + x;
      for (int j = cell_start_[cell]; j < cell_start_[cell + 1]; ++j) {
        const int i = cell_items_[j];
        const Eigen::Vector2f& p = features_.keypoints[i].pixel;
        const float dx = p.x() - cx, dy = p.y() - cy;
        if (dx * dx + dy * dy <= r2) visit(i);
      }
    }
  }
}

}  // namespace visloc
