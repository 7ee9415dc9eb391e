#include "core/localization/map_matching.h"

#include <limits>
#include <optional>

#include "core/features/descriptor.h"
#include "core/util/check.h"

namespace visloc {

std::vector<ProjectedPoint> ProjectPoints(const PointView& map_points, const Camera& camera,
                                          const Rigid3d& cam_from_map,
                                          const std::vector<uint32_t>& points) {
  std::vector<ProjectedPoint> projected;
  projected.reserve(points.size());
  for (uint32_t point : points) {
    const Eigen::Vector3d in_cam = cam_from_map * map_points.position(point);
    ProjectedPoint p{point, Eigen::Vector2d::Zero()};
    if (in_cam.z() > 0.05 && camera.Project(in_cam, &p.pixel) && camera.IsInImage(p.pixel)) {
      projected.push_back(p);
    }
  }
  return projected;
}

std::vector<PointMatch> MatchProjected(const PointView& map_points,
                                       const std::vector<ProjectedPoint>& projected,
                                       const QueryFrame& frame, double radius_px,
                                       const DescriptorMatchOptions& options) {
  std::vector<GuidedQuery> queries(projected.size());
  for (size_t q = 0; q < projected.size(); ++q) {
    int row = 0;
    const cv::Mat& descriptors = map_points.descriptors(projected[q].point, &row);
    queries[q] = {&descriptors, row, projected[q].pixel};
  }
  std::vector<PointMatch> matches;
  for (const GuidedMatch& m :
       MatchGuided(queries, frame.grid(), frame.features().descriptors, radius_px, options)) {
    matches.push_back({projected[m.query].point, m.keypoint, m.distance});
  }
  return matches;
}

namespace {

// The points' descriptors as one matrix and each point's row in it: the map's own matrix for a
// resident map, the points' rows gathered from their chunks for a paged one.
const cv::Mat& DescriptorRows(const PointView& map_points, const std::vector<uint32_t>& points,
                              cv::Mat* gathered, std::vector<uint32_t>* rows) {
  if (const cv::Mat* all = map_points.all_descriptors()) {
    *rows = points;
    return *all;
  }
  rows->resize(points.size());
  for (size_t j = 0; j < points.size(); ++j) {
    int row = 0;
    const cv::Mat& source = map_points.descriptors(points[j], &row);
    if (gathered->empty())
      gathered->create(static_cast<int>(points.size()), source.cols, source.type());
    source.row(row).copyTo(gathered->row(static_cast<int>(j)));
    (*rows)[j] = static_cast<uint32_t>(j);
  }
  return *gathered;
}

}  // namespace

std::vector<PointMatch> MatchByDescriptor(const PointView& map_points,
                                          const std::vector<uint32_t>& points,
                                          const QueryFrame& frame,
                                          const DescriptorMatchOptions& options) {
  const cv::Mat& frame_descriptors = frame.features().descriptors;
  if (points.empty()) return {};
  cv::Mat gathered;
  std::vector<uint32_t> rows;
  const cv::Mat& descriptors = DescriptorRows(map_points, points, &gathered, &rows);
  const float max_distance = options.MaxDistance(
      descriptors.type() == CV_32F ? DescriptorType::kFloat32 : DescriptorType::kBinary);
  // Keypoint -> nearest point with the ratio test, then one keypoint per point.
  std::vector<PointMatch> per_point(points.size(), {0u, -1, std::numeric_limits<float>::max()});
  // 16-float descriptors (harris_surf16) go eight points at a time through their columns.
  std::optional<Float16Columns> columns;
  if (descriptors.type() == CV_32F && descriptors.cols == 16) {
    columns.emplace(descriptors, rows);
    VISLOC_CHECK(
        frame.size() == 0 || (frame_descriptors.type() == CV_32F && frame_descriptors.cols == 16),
        "the frame's descriptors are not the map's (16 floats)");
  }
  for (int i = 0; i < static_cast<int>(frame.size()); ++i) {
    NearestTwo nearest;
    if (columns) {
      nearest = columns->Nearest(frame_descriptors.ptr<float>(i));
    } else {
      for (size_t j = 0; j < points.size(); ++j) {
        nearest.Offer(
            DescriptorDistance(frame_descriptors, i, descriptors, static_cast<int>(rows[j])),
            static_cast<int>(j));
      }
    }
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
