#include "core/localization/query_frame.h"

namespace visloc {

QueryFrame::QueryFrame(FeatureSet features, const PinholeCamera& camera, int cell_px)
    : features_(std::move(features)) {
  const int n = static_cast<int>(features_.size());
  normalized_.resize(n);
  std::vector<Eigen::Vector2f> pixels(n);
  for (int i = 0; i < n; ++i) {
    pixels[i] = features_.keypoints[i].pixel;
    const Eigen::Vector3d ray = camera.Unproject(pixels[i].cast<double>());
    normalized_[i] = ray.head<2>() / ray.z();
  }
  grid_ = KeypointGrid(std::move(pixels), camera.width(), camera.height(), cell_px);
}

}  // namespace visloc
