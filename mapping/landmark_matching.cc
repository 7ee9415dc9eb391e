#include "mapping/landmark_matching.h"

namespace visloc::mapping {

RectifiedView ViewOf(const StereoRectifier& rectifier) {
  const Eigen::Vector2d size(rectifier.canvas_size().width, rectifier.canvas_size().height);
  const Eigen::Vector2d low = -rectifier.canvas_offset_px() - Eigen::Vector2d(0.5, 0.5);
  return {rectifier.rectified_camera(), Eigen::AlignedBox2d(low, low + size)};
}

std::vector<LandmarkMatch> MatchLandmarks(const SlamState& state, const KeypointGrid& grid,
                                          const cv::Mat& descriptors, const RectifiedView& view,
                                          const Rigid3d& cam_from_world,
                                          const std::vector<int>& landmarks, double radius_px,
                                          const DescriptorMatchOptions& options,
                                          std::vector<int>* in_view) {
  if (in_view) in_view->clear();
  std::vector<GuidedQuery> queries;
  std::vector<int> query_landmark;
  for (int l : landmarks) {
    const Landmark& landmark = state.landmarks[l];
    const Eigen::Vector3d p = cam_from_world * landmark.position_in_world;
    if (p.z() < 0.1) continue;  // Behind, or too close to project stably.
    Eigen::Vector2d projected;
    if (!view.camera.Project(p, &projected) || !view.region.contains(projected)) continue;
    if (in_view) in_view->push_back(l);
    const auto& [k, i] = landmark.observations.back();
    queries.push_back({&state.keyframes[k].features.descriptors, i, projected});
    query_landmark.push_back(l);
  }
  std::vector<LandmarkMatch> matches;
  for (const GuidedMatch& m : MatchGuided(queries, grid, descriptors, radius_px, options)) {
    matches.push_back({query_landmark[m.query], m.keypoint});
  }
  return matches;
}

}  // namespace visloc::mapping
