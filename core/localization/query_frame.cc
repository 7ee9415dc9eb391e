#include "core/localization/query_frame.h"

namespace visloc {

QueryFrame::QueryFrame(FeatureSet features, const Camera& camera, int cell_px) {
  const int n = static_cast<int>(features.size());
  std::vector<Eigen::Vector2f> pixels(n);
  for (int i = 0; i < n; ++i) pixels[i] = features.keypoints[i].pixel;
  camera.UnprojectMany(pixels, &normalized_, &pixel_scale_);
  // Rays 90 degrees or more off the axis (a fisheye's corners) are left out.
  std::vector<int> kept;
  kept.reserve(n);
  for (int i = 0; i < n; ++i) {
    if (normalized_[i].allFinite()) kept.push_back(i);
  }
  if (static_cast<int>(kept.size()) < n) {
    for (size_t j = 0; j < kept.size(); ++j) {
      pixels[j] = pixels[kept[j]];
      normalized_[j] = normalized_[kept[j]];
      pixel_scale_[j] = pixel_scale_[kept[j]];
    }
    pixels.resize(kept.size());
    normalized_.resize(kept.size());
    pixel_scale_.resize(kept.size());
  }
  features_ = static_cast<int>(kept.size()) == n ? std::move(features) : features.Subset(kept);
  grid_ = KeypointGrid(std::move(pixels), camera.width(), camera.height(), cell_px);
}

}  // namespace visloc
