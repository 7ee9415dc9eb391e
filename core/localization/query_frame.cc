#include "core/localization/query_frame.h"

namespace visloc {

QueryFrame::QueryFrame(FeatureSet features, const Camera& camera, int cell_px) {
  const int n = static_cast<int>(features.size());
  normalized_.reserve(n);
  pixel_scale_.reserve(n);
  std::vector<Eigen::Vector2f> pixels;
  pixels.reserve(n);
  std::vector<int> kept;
  const bool ideal = camera.lens().IsIdeal();
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector2f& pixel = features.keypoints[i].pixel;
    const Eigen::Vector3d ray = camera.Unproject(pixel.cast<double>());
    if (!ray.allFinite()) continue;
    kept.push_back(i);
    pixels.push_back(pixel);
    normalized_.push_back(ray.head<2>());
    pixel_scale_.push_back(ideal ? 1.0 : camera.PixelScale(ray.head<2>()));
  }
  features_ = static_cast<int>(kept.size()) == n ? std::move(features) : features.Subset(kept);
  grid_ = KeypointGrid(std::move(pixels), camera.width(), camera.height(), cell_px);
}

}  // namespace visloc
