#include "core/localization/pose_tracker.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>

#include "core/util/check.h"
#include "core/util/timer.h"

namespace visloc {

const char* PredictionModeName(PredictionMode mode) {
  switch (mode) {
    case PredictionMode::kVisibility:
      return "visibility";
    case PredictionMode::kTransparent:
      return "transparent";
    case PredictionMode::kBruteForce:
      return "brute_force";
  }
  return "?";
}

PredictionMode ParsePredictionMode(const std::string& name) {
  for (PredictionMode mode :
       {PredictionMode::kVisibility, PredictionMode::kTransparent, PredictionMode::kBruteForce}) {
    if (name == PredictionModeName(mode)) return mode;
  }
  throw InputError("unknown prediction mode '" + name +
                   "' (known: visibility, transparent, brute_force)");
}

void PoseTrackerOptions::Check() const {
  visibility.Check();
  ransac.Check();
  matching.Check();
  VISLOC_CHECK(search_radius_px > 0 && refine_radius_px > 0, "search radii ", search_radius_px, " ",
               refine_radius_px);
  VISLOC_CHECK(coarse_points >= 0 && rig_min_coarse_points >= 0, "coarse_points ", coarse_points,
               ", rig_min_coarse_points ", rig_min_coarse_points);
  VISLOC_CHECK(map_error_px >= 0 && map_floor_m >= 0 && map_drift_fraction >= 0,
               "map error: ", map_error_px, " px, ", map_floor_m, " m, drift ", map_drift_fraction);
  VISLOC_CHECK(point_error_gain >= 0 && covariance_points >= 0, "point_error_gain ",
               point_error_gain, ", covariance_points ", covariance_points);
  VISLOC_CHECK(rig_floor_m >= 0 && rig_drift_fraction >= 0, "rig error: ", rig_floor_m, " m, drift ",
               rig_drift_fraction);
}

PoseTracker::PoseTracker(std::shared_ptr<const LocalizationMap> map, const Camera& camera,
                         const PoseTrackerOptions& options)
    : map_(std::move(map)), camera_(camera), options_(options) {
  VISLOC_CHECK(map_ != nullptr, "no map");
  options_.Check();
  options_.ransac.refine.focal_px = camera_.fx();
  VISLOC_CHECK(!map_->paged() || options_.prediction == PredictionMode::kVisibility,
               "a paged map predicts with its visibility kernel only (the ",
               PredictionModeName(options_.prediction), " baseline needs the whole map resident)");
  if (options_.prediction == PredictionMode::kVisibility) {
    predictor_ = std::make_unique<VisibilityPredictor>(*map_, options_.visibility);
  }
  if (options_.prediction == PredictionMode::kBruteForce) {
    all_points_.resize(map_->point_count());
    std::iota(all_points_.begin(), all_points_.end(), 0u);
  }
}

std::vector<PoseObservation> PoseTracker::Observations(
    const PointView& map_points, const QueryFrame& frame,
    const std::vector<PointMatch>& matches) const {
  std::vector<PoseObservation> observations(matches.size());
  for (size_t m = 0; m < matches.size(); ++m) {
    observations[m].point_in_world = map_points.position(matches[m].point);
    observations[m].normalized = frame.normalized(matches[m].feature);
    observations[m].pixel_scale = frame.pixel_scale(matches[m].feature);
  }
  return observations;
}

std::vector<uint32_t> PoseTracker::PredictPoints(const Rigid3d& cam_from_map, PoseFix* fix) const {
  Timer timer;
  std::vector<uint32_t> points;
  if (predictor_) {
    for (const PredictedPoint& p : predictor_->Predict(cam_from_map.Inverse())) {
      points.push_back(p.point);
    }
  } else {
    points = PredictTransparentWorld(*map_, camera_, cam_from_map.Inverse());
  }
  fix->predicted = static_cast<int>(points.size());
  fix->times.predict_ms += timer.ElapsedMs();
  return points;
}

Eigen::Matrix<double, 6, 6> PoseTracker::SystematicCovariance(
    const std::vector<PoseObservation>& observations, const std::vector<char>& inliers,
    const Rigid3d& cam_from_map) const {
  std::vector<double> depths;
  for (size_t m = 0; m < observations.size(); ++m) {
    if (inliers[m]) depths.push_back((cam_from_map * observations[m].point_in_world).z());
  }
  std::nth_element(depths.begin(), depths.begin() + depths.size() / 2, depths.end());
  const double median_depth_m = depths.empty() ? 0.0 : depths[depths.size() / 2];
  return MapAndRigCovariance(median_depth_m, cam_from_map.Inverse().translation.norm());
}

Eigen::Matrix<double, 6, 6> PoseTracker::MapAndRigCovariance(double median_depth_m,
                                                             double from_origin_m) const {
  return visloc::MapAndRigCovariance(options_, map_->map().metadata, camera_.fx(), median_depth_m,
                                     from_origin_m);
}

Eigen::Matrix<double, 6, 6> MapAndRigCovariance(const PoseTrackerOptions& options,
                                                const MapMetadata& metadata, double focal_px,
                                                double median_depth_m, double from_origin_m) {
  const double angle_rad = options.map_error_px / focal_px;
  const RigError rig =
      metadata.rig_error.value_or(RigError{options.rig_floor_m, options.rig_drift_fraction});
  const double floor_sq = std::pow(options.map_floor_m, 2) + std::pow(rig.floor_m, 2);
  const double drift_sq = std::pow(options.map_drift_fraction, 2) + std::pow(rig.drift_fraction, 2);
  const double position_variance =
      std::pow(angle_rad * median_depth_m, 2) + floor_sq + drift_sq * from_origin_m * from_origin_m;
  Eigen::Matrix<double, 6, 6> covariance = Eigen::Matrix<double, 6, 6>::Zero();
  covariance.diagonal() << Eigen::Vector3d::Constant(position_variance),
      Eigen::Vector3d::Constant(angle_rad * angle_rad);
  return covariance;
}

Eigen::Matrix<double, 6, 6> PointSpread::Matrix() const {
  Eigen::Matrix<double, 6, 6> spread;
  int k = 0;
  for (int a = 0; a < 6; ++a) {
    for (int b = a; b < 6; ++b) spread(a, b) = spread(b, a) = upper[k++];
  }
  return spread;
}

PointSpread PoseTracker::PointSpreadOf(const PointView& map_points,
                                       const std::vector<PointMatch>& matches,
                                       const std::vector<PoseObservation>& observations,
                                       const std::vector<char>& inliers,
                                       const Rigid3d& cam_from_map) const {
  PointSpread spread;
  const size_t inlier_count = static_cast<size_t>(std::count(inliers.begin(), inliers.end(), 1));
  if (inlier_count == 0) return spread;
  // The sum over the inliers of J^T Omega J, J the projection's rows by the pose (2x6, the left
  // perturbation of pose_refinement.cc) and Omega = B Sigma B^T the point's covariance Sigma
  // moved into the image by B, the projection's rows by the point (2x3). Over an even sample of
  // at most covariance_points inliers, scaled to all of them: a sum of hundreds of like terms,
  // estimated to a few percent by a third of them, at a third of the time.
  const size_t stride =
      options_.covariance_points > 0
          ? (inlier_count + options_.covariance_points - 1) / options_.covariance_points
          : 1;
  std::array<double, 21> upper{};  // Row by row.
  size_t summed = 0;
  const Eigen::Matrix3d rotation = cam_from_map.rotation.toRotationMatrix();
  size_t inlier_index = 0;  // Of the inlier m is, among the inliers.
  for (size_t m = 0; m < matches.size(); ++m) {
    if (!inliers[m] || inlier_index++ % stride != 0) continue;
    const PointCovariance* packed = map_points.covariance(matches[m].point);
    if (packed == nullptr) {
      spread.unknown = true;
      return spread;
    }
    const PoseObservation& o = observations[m];
    const double z = rotation.row(2).dot(o.point_in_world) + cam_from_map.translation.z();
    if (z <= 1e-6) continue;
    // An inlier's projection is within a pixel or two of its keypoint: the keypoint's
    // normalized coordinates serve as the projection's in the Jacobians.
    const double iz = 1.0 / z, u = o.normalized.x(), v = o.normalized.y();
    // B = iz [1 0 -u; 0 1 -v] R, row by row.
    const Eigen::Vector3d b1 = iz * (rotation.row(0) - u * rotation.row(2)).transpose();
    const Eigen::Vector3d b2 = iz * (rotation.row(1) - v * rotation.row(2)).transpose();
    const Eigen::Vector3d sigma_b1 = SymmetricTimes(*packed, b1);
    const Eigen::Vector3d sigma_b2 = SymmetricTimes(*packed, b2);
    // Weighed as the refinement weighs a residual and its rows: by the lens's pixel scale,
    // squared twice (the rows on both sides and Omega's own two).
    const double s = o.pixel_scale, weight = s * s * s * s;
    const double o11 = weight * b1.dot(sigma_b1), o12 = weight * b1.dot(sigma_b2),
                 o22 = weight * b2.dot(sigma_b2);
    const double j1[6] = {iz, 0.0, -u * iz, -u * v, 1.0 + u * u, -v};
    const double j2[6] = {0.0, iz, -v * iz, -(1.0 + v * v), u * v, u};
    int k = 0;
    for (int a = 0; a < 6; ++a) {
      // Row a of J^T Omega J: (j1[a] o11 + j2[a] o12) j1 + (j1[a] o12 + j2[a] o22) j2.
      const double w1 = j1[a] * o11 + j2[a] * o12, w2 = j1[a] * o12 + j2[a] * o22;
      for (int b = a; b < 6; ++b) upper[k++] += w1 * j1[b] + w2 * j2[b];
    }
    ++summed;
  }
  if (summed == 0) return spread;
  spread.upper = upper;
  spread.to_all = static_cast<double>(inlier_count) / static_cast<double>(summed);
  return spread;
}

Eigen::Matrix<double, 6, 6> PoseTracker::PointsCovariance(
    const PointView& map_points, const std::vector<PointMatch>& matches,
    const std::vector<PoseObservation>& observations, const std::vector<char>& inliers,
    const Rigid3d& cam_from_map, const Eigen::Matrix<double, 6, 6>& inverse_information) const {
  using Matrix6d = Eigen::Matrix<double, 6, 6>;
  if (options_.point_error_gain == 0) return Matrix6d::Zero();
  const PointSpread spread =
      PointSpreadOf(map_points, matches, observations, inliers, cam_from_map);
  if (spread.unknown) return Matrix6d::Zero();
  return options_.point_error_gain * spread.to_all * inverse_information * spread.Matrix() *
         inverse_information;
}

void PoseTracker::RefineAround(const PointView& map_points, const QueryFrame& frame,
                               const std::vector<uint32_t>& points, const Rigid3d& cam_from_map,
                               double radius_px, PoseFix* fix) const {
  Timer timer;
  const std::vector<ProjectedPoint> projected =
      ProjectPoints(map_points, camera_, cam_from_map, points);
  fix->times.project_ms += timer.ElapsedMs();
  timer.Restart();
  const std::vector<PointMatch> matches =
      MatchProjected(map_points, projected, frame, radius_px, options_.matching);
  fix->times.match_ms += timer.ElapsedMs();
  timer.Restart();
  const std::vector<PoseObservation> observations = Observations(map_points, frame, matches);
  const PnpResult refined = RefinePoseOnInliers(cam_from_map, observations, options_.ransac);
  fix->times.pose_ms += timer.ElapsedMs();
  fix->putatives = static_cast<int>(matches.size());
  fix->success = refined.success;
  if (!refined.success) {
    fix->inliers = 0;
    fix->inlier_ratio = 0.0;
    return;
  }
  fix->cam_from_map = refined.cam_from_world;
  fix->inliers = refined.stats.inliers;
  fix->inlier_ratio = refined.stats.inlier_ratio;
  fix->reproj_rmse_px = refined.stats.refine.final_rmse_px;
  timer.Restart();
  SetCovariances(map_points, matches, observations, refined, fix);
  fix->times.pose_ms += timer.ElapsedMs();
  fix->inlier_cells = InlierCells(frame, matches, refined.inlier_mask);
}

void PoseTracker::SetCovariances(const PointView& map_points, const std::vector<PointMatch>& matches,
                                 const std::vector<PoseObservation>& observations,
                                 const PnpResult& refined, PoseFix* fix) const {
  // A posteriori noise: scale the unit-pixel covariance by the measured residual (floored,
  // since a handful of perfect synthetic matches would otherwise claim micrometres).
  const double sigma_px = std::max(0.3, fix->reproj_rmse_px);
  const double unit = options_.ransac.refine.pixel_sigma_px;
  fix->covariance = refined.covariance * (sigma_px * sigma_px) / (unit * unit);
  // The refinement's covariance is sigma^2 (J^T J)^-1 in normalized units, sigma = unit / focal.
  const double unit_normalized = unit / options_.ransac.refine.focal_px;
  const Eigen::Matrix<double, 6, 6> from_points =
      PointsCovariance(map_points, matches, observations, refined.inlier_mask, fix->cam_from_map,
                       refined.covariance / (unit_normalized * unit_normalized));
  const Eigen::Matrix<double, 6, 6> map_and_rig =
      SystematicCovariance(observations, refined.inlier_mask, fix->cam_from_map);
  fix->systematic_covariance = map_and_rig + from_points;
  const double rest_variance = (fix->covariance + map_and_rig).topLeftCorner<3, 3>().trace();
  fix->point_variance_ratio =
      rest_variance > 0 ? from_points.topLeftCorner<3, 3>().trace() / rest_variance : 0.0;
}

int PoseTracker::InlierCells(const QueryFrame& frame, const std::vector<PointMatch>& matches,
                             const std::vector<char>& inliers) const {
  constexpr int kCols = PoseFix::kCoverageCols, kRows = PoseFix::kCoverageRows;
  std::array<bool, kCols * kRows> occupied{};
  for (size_t m = 0; m < matches.size(); ++m) {
    if (!inliers[m]) continue;
    const Eigen::Vector2f& pixel = frame.features().keypoints[matches[m].feature].pixel;
    const int col = std::clamp(static_cast<int>(pixel.x() * kCols / camera_.width()), 0, kCols - 1);
    const int row = std::clamp(static_cast<int>(pixel.y() * kRows / camera_.height()), 0, kRows - 1);
    occupied[row * kCols + col] = true;
  }
  return static_cast<int>(std::count(occupied.begin(), occupied.end(), true));
}

const std::vector<ProjectedPoint>& PoseTracker::CoarseSubset(
    const std::vector<ProjectedPoint>& projected, int wanted,
    std::vector<ProjectedPoint>* subset) const {
  if (wanted == 0 || static_cast<int>(projected.size()) <= wanted) return projected;
  std::vector<Eigen::Vector2f> pixels;
  pixels.reserve(projected.size());
  for (const ProjectedPoint& p : projected) pixels.push_back(p.pixel.cast<float>());
  subset->clear();
  for (int i : SpreadOverGrid(pixels, cv::Size(camera_.width(), camera_.height()), 8, 6, wanted)) {
    subset->push_back(projected[i]);
  }
  return *subset;
}

PnpResult PoseTracker::SolveFromMatches(const PointView& map_points, const QueryFrame& frame,
                                        const std::vector<PointMatch>& matches,
                                        PoseFix* fix) const {
  Timer timer;
  // One refinement pass: RefineAround re-matches around this pose and refines twice anyway.
  PnpRansacOptions ransac_options = options_.ransac;
  ransac_options.refinement_passes = 1;
  const PnpResult ransac = SolvePnpRansac(Observations(map_points, frame, matches), ransac_options);
  fix->times.pose_ms += timer.ElapsedMs();
  fix->ransac_iterations += ransac.stats.iterations;
  fix->putatives = static_cast<int>(matches.size());
  return ransac;
}

PoseFix PoseTracker::Track(const QueryFrame& frame, const Rigid3d& prior_cam_from_map) const {
  PoseFix fix;
  std::vector<uint32_t> points;
  PnpResult ransac;
  Timer timer;
  if (options_.prediction == PredictionMode::kBruteForce) {
    const PointView all = map_->AllPoints();
    const std::vector<PointMatch> matches =
        MatchByDescriptor(all, all_points_, frame, options_.matching);
    fix.times.match_ms += timer.ElapsedMs();
    ransac = SolveFromMatches(all, frame, matches, &fix);
    if (!ransac.success) return fix;
    points = PredictPoints(ransac.cam_from_world, &fix);
    RefineAround(all, frame, points, ransac.cam_from_world, options_.refine_radius_px, &fix);
    return fix;
  }
  points = PredictPoints(prior_cam_from_map, &fix);
  timer.Restart();
  // A paged map loads the chunks these points lie in, if they are not cached (predict time).
  const PointView map_points = map_->Points(points);
  fix.times.predict_ms += timer.ElapsedMs();
  timer.Restart();
  const std::vector<ProjectedPoint> projected =
      ProjectPoints(map_points, camera_, prior_cam_from_map, points);
  std::vector<ProjectedPoint> subset;
  const std::vector<ProjectedPoint>& coarse =
      CoarseSubset(projected, options_.coarse_points, &subset);
  fix.times.project_ms += timer.ElapsedMs();
  timer.Restart();
  std::vector<PointMatch> matches =
      MatchProjected(map_points, coarse, frame, options_.search_radius_px, options_.matching);
  fix.times.match_ms += timer.ElapsedMs();
  ransac = SolveFromMatches(map_points, frame, matches, &fix);
  if (!ransac.success && coarse.size() < projected.size()) {
    timer.Restart();
    matches =
        MatchProjected(map_points, projected, frame, options_.search_radius_px, options_.matching);
    fix.times.match_ms += timer.ElapsedMs();
    ransac = SolveFromMatches(map_points, frame, matches, &fix);
  }
  if (!ransac.success) return fix;
  RefineAround(map_points, frame, points, ransac.cam_from_world, options_.refine_radius_px, &fix);
  return fix;
}

PoseFix PoseTracker::Polish(const QueryFrame& frame, const Rigid3d& cam_from_map) const {
  PoseFix fix;
  const std::vector<uint32_t> points = PredictPoints(cam_from_map, &fix);
  RefineAround(map_->Points(points), frame, points, cam_from_map, options_.refine_radius_px, &fix);
  return fix;
}

}  // namespace visloc
