#include "core/localization/query_frame.h"

#include <algorithm>

#include "core/util/check.h"

namespace visloc {

QueryFrame::QueryFrame(FeatureSet features, const PinholeCamera& camera, int cell_px)
    : features_(std::move(features)), cell_px_(cell_px) {
  VISLOC_CHECK(cell_px > 0, "grid cell ", cell_px);
  cols_ = camera.width() / cell_px_ + 1;
  rows_ = camera.height() / cell_px_ + 1;
  const int n = static_cast<int>(features_.size());
  normalized_.resize(n);
  std::vector<int> cell_of(n);
  cell_start_.assign(cols_ * rows_ + 1, 0);
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector2f& p = features_.keypoints[i].pixel;
    const Eigen::Vector3d ray = camera.Unproject(p.cast<double>());
    normalized_[i] = ray.head<2>() / ray.z();
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

}  // namespace visloc
