#include "core/localization/map_matching.h"

#include <limits>
#include <optional>

#include "core/map/descriptor.h"
#include "core/util/check.h"

namespace visloc {
namespace {

// Keeps, per keypoint, the closest map point that claimed it.
class KeypointClaims {
 public:
  explicit KeypointClaims(size_t keypoints)
      : best_(keypoints, {0u, std::numeric_limits<float>::max()}), claimed_(keypoints, 0) {}
  void Offer(uint32_t point, int feature, float distance) {
    if (distance < best_[feature].second) best_[feature] = {point, distance};
    claimed_[feature] = 1;
  }
  std::vector<PointMatch> Matches() const {
    std::vector<PointMatch> matches;
    for (size_t i = 0; i < best_.size(); ++i) {
      if (claimed_[i]) matches.push_back({best_[i].first, static_cast<int>(i), best_[i].second});
    }
    return matches;
  }

 private:
  std::vector<std::pair<uint32_t, float>> best_;
  std::vector<char> claimed_;
};

}  // namespace

std::vector<ProjectedPoint> ProjectPoints(const Map& map, const PinholeCamera& camera,
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
                                       const QueryFrame& frame, const MatchOptions& options) {
  const cv::Mat& frame_descriptors = frame.features().descriptors;
  const float max_distance = options.MaxDistance(map.features.descriptor_type);
  KeypointClaims claims(frame.size());
  for (const ProjectedPoint& p : projected) {
    NearestTwo nearest;
    frame.ForEachWithin(p.pixel, options.radius_px, [&](int i) {
      nearest.Offer(
          DescriptorDistance(map.descriptors, static_cast<int>(p.point), frame_descriptors, i), i);
    });
    if (nearest.Distinctive(options.ratio, max_distance)) {
      claims.Offer(p.point, nearest.best_index, nearest.best);
    }
  }
  return claims.Matches();
}

std::vector<PointMatch> MatchByDescriptor(const Map& map, const std::vector<uint32_t>& points,
                                          const QueryFrame& frame, const MatchOptions& options) {
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
