#include "core/localization/map_matching.h"

#include <limits>
#include <optional>

#include "core/features/descriptor.h"
#include "core/util/check.h"

namespace visloc {

std::vector<ProjectedPoint> ProjectPoints(const Map& map, const Camera& camera,
                                          const Rigid3d& cam_from_map,
                                          const std::vector<uint32_t>& points) {
  std::vector<ProjectedPoint> projected;
  projected.reserve(points.size());
  for (uint32_t point : points) {
    const Eigen::Vector3d in_cam = cam_from_map * map.points[point].position_in_map;
    ProjectedPoint p{point, Eigen::Vector2d::Zero()};
    if (in_cam.z() > 0.05 && camera.Project(in_cam, &p.pixel) && camera.IsInImage(p.pixel)) {
      projected.push_back(p);
    }
  }
  return projected;
}

std::vector<PointMatch> MatchProjected(const Map& map, const std::vector<ProjectedPoint>& projected,
                                       const QueryFrame& frame, double radius_px,
                                       const DescriptorMatchOptions& options) {
  std::vector<GuidedQuery> queries(projected.size());
  for (size_t q = 0; q < projected.size(); ++q) {
    queries[q] = {&map.descriptors, static_cast<int>(projected[q].point), projected[q].pixel};
  }
  std::vector<PointMatch> matches;
  for (const GuidedMatch& m :
       MatchGuided(queries, frame.grid(), frame.features().descriptors, radius_px, options)) {
    matches.push_back({projected[m.query].point, m.keypoint, m.distance});
  }
  return matches;
}

std::vector<PointMatch> MatchByDescriptor(const Map& map, const std::vector<uint32_t>& points,
                                          const QueryFrame& frame,
                                          const DescriptorMatchOptions& options) {
  const cv::Mat& frame_descriptors = frame.features().descriptors;
  const float max_distance = options.MaxDistance(map.features.descriptor_type);
  // Keypoint -> nearest point with the ratio test, then one keypoint per point.
  std::vector<PointMatch> per_point(points.size(), {0u, -1, std::numeric_limits<float>::max()});
  // 16-float descriptors (harris_surf16) go eight points at a time through their columns.
  std::optional<Float16Columns> columns;
  if (map.descriptors.type() == CV_32F && map.descriptors.cols == 16) {
    columns.emplace(map.descriptors, points);
    VISLOC_CHECK(
        frame.size() == 0 || (frame_descriptors.type() == CV_32F && frame_descriptors.cols == 16),
        "the frame's descriptors are not the map's (16 floats)");
  }
  std::vector<float> distances(points.size());
  for (int i = 0; i < static_cast<int>(frame.size()); ++i) {
    if (columns) {
      columns->Distances(frame_descriptors.ptr<float>(i), distances.data());
    } else {
      for (size_t j = 0; j < points.size(); ++j) {
        distances[j] =
            DescriptorDistance(frame_descriptors, i, map.descriptors, static_cast<int>(points[j]));
      }
    }
    NearestTwo nearest;
    for (size_t j = 0; j < points.size(); ++j) nearest.Offer(distances[j], static_cast<int>(j));
    if (!nearest.Distinctive(options.ratio, max_distance)) continue;
    PointMatch& claim = per_point[nearest.best_index];
    if (nearest.best < claim.distance) claim = {points[nearest.best_index], i, nearest.best};
  }
  std::vector<PointMatch> matches;
  for (const PointMatch& m : per_point) {
    if (m.feature >= 0) matches.push_back(m);
  }
  return matches;
}

}  // namespace visloc
