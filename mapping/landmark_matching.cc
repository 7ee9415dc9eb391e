#include "mapping/landmark_matching.h"

namespace visloc::mapping {

std::vector<LandmarkMatch> MatchLandmarks(const SlamState& state, const KeypointGrid& grid,
                                          const cv::Mat& descriptors,
                                          const PinholeCamera& rectified_camera,
                                          const Rigid3d& cam_from_world,
                                          const std::vector<int>& landmarks, double radius_px,
                                          const DescriptorMatchOptions& options) {
  std::vector<GuidedQuery> queries;
  std::vector<int> query_landmark;
  for (int l : landmarks) {
    const Landmark& landmark = state.landmarks[l];
    const Eigen::Vector3d p = cam_from_world * landmark.position_in_world;
    if (p.z() < 0.1) continue;  // Behind, or too close to project stably.
    Eigen::Vector2d projected;
    if (!rectified_camera.Project(p, &projected) || !rectified_camera.IsInImage(projected)) continue;
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
