#pragma once
// Data association between a query frame and map points.
//
// Guided (tracking): predicted-visible points are projected with the prior pose and each is
// matched to the most similar keypoint within a search radius of its projection (seed paper
// 000, sec. 5). Unguided (relocalization and the brute-force baseline): every keypoint is
// compared with every given point's descriptor. Both keep a match only when it is close in
// descriptor space, clearly better than the runner-up (Lowe's ratio test), and the best claim
// on its keypoint (one map point per keypoint).

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "core/camera/camera.h"
#include "core/geometry/rigid3.h"
#include "core/localization/query_frame.h"
#include "core/map/localization_map.h"

namespace visloc {

struct ProjectedPoint {
  uint32_t point = 0;
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();  // Raw (distorted) image pixels.
};

struct PointMatch {
  uint32_t point = 0;
  int feature = 0;  // Keypoint index in the query frame.
  float distance = 0.0f;
};

// The points (ids into the map's points, all in `map_points`) that lie in front of the camera at
// `cam_from_map` and project inside its image.
std::vector<ProjectedPoint> ProjectPoints(const PointView& map_points, const Camera& camera,
                                          const Rigid3d& cam_from_map,
                                          const std::vector<uint32_t>& points);

// Guided matching (MatchGuided) of projected points to the frame's keypoints within
// `radius_px` of their projections.
std::vector<PointMatch> MatchProjected(const PointView& map_points,
                                       const std::vector<ProjectedPoint>& projected,
                                       const QueryFrame& frame, double radius_px,
                                       const DescriptorMatchOptions& options);

// Unguided matching of all the frame's keypoints against `points` by descriptor alone.
std::vector<PointMatch> MatchByDescriptor(const PointView& map_points,
                                          const std::vector<uint32_t>& points,
                                          const QueryFrame& frame,
                                          const DescriptorMatchOptions& options);

}  // namespace visloc
