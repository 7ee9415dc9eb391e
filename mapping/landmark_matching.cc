#include "mapping/landmark_matching.h"

namespace visloc::mapping {

RectifiedView ViewOf(const StereoRectifier& rectifier) {
  const Eigen::Vector2d size(rectifier.canvas_size().width, rectifier.canvas_size().height);
  const Eigen::Vector2d low = -rectifier.canvas_offset_px() - Eigen::Vector2d(0.5, 0.5);
  return {rectifier.rectified_camera(), Eigen::AlignedBox2d(low, low + size)};
}

std::vector<ProjectedLandmark> ProjectLandmarks(const SlamState& state, const RectifiedView& view,
                                                const Rigid3d& cam_from_world,
                                                const std::vector<int>& landmarks) {
  std::vector<ProjectedLandmark> projected;
  for (int l : landmarks) {
    const Eigen::Vector3d p = cam_from_world * state.landmarks[l].position_in_world;
    if (p.z() < 0.1) continue;  // Behind, or too close to project stably.
    Eigen::Vector2d pixel;
    if (!view.camera.Project(p, &pixel) || !view.region.contains(pixel)) continue;
    projected.push_back({l, pixel});
  }
  return projected;
}

std::vector<LandmarkMatch> MatchLandmarks(const SlamState& state, const KeypointGrid& grid,
                                          const cv::Mat& descriptors, const RectifiedView& view,
                                          const Rigid3d& cam_from_world,
                                          const std::vector<int>& landmarks, double radius_px,
                                          const DescriptorMatchOptions& options,
                                          std::vector<int>* in_view) {
  const std::vector<ProjectedLandmark> projected =
      ProjectLandmarks(state, view, cam_from_world, landmarks);
  if (in_view) {
    in_view->clear();
    for (const ProjectedLandmark& p : projected) in_view->push_back(p.landmark);
  }
  std::vector<GuidedQuery> queries;
  queries.reserve(projected.size());
  for (const ProjectedLandmark& p : projected) {
    const auto& [k, i] = state.landmarks[p.landmark].observations.back();
    queries.push_back({&state.keyframes[k].features.descriptors, i, p.pixel});
  }
  std::vector<LandmarkMatch> matches;
  for (const GuidedMatch& m : MatchGuided(queries, grid, descriptors, radius_px, options)) {
    matches.push_back({projected[m.query].landmark, m.keypoint});
  }
  return matches;
}

}  // namespace visloc::mapping
