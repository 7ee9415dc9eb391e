#include "core/localization/localizability.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>

#include <Eigen/Eigenvalues>

#include "core/localization/pose_tracker.h"
#include "core/map/point_uncertainty.h"
#include "core/map/visibility_kernel.h"
#include "core/util/check.h"
#include "core/util/parallel.h"
#include "core/util/timer.h"

namespace visloc {
namespace {

using Matrix6d = Eigen::Matrix<double, 6, 6>;
using Matrix26d = Eigen::Matrix<double, 2, 6>;

double Median(std::vector<double> values) {
  if (values.empty()) return 0.0;
  const size_t mid = values.size() / 2;
  std::nth_element(values.begin(), values.begin() + mid, values.end());
  return values[mid];
}

// Per thread: each point's best kernel weight so far, and which points were touched.
struct Scratch {
  std::vector<float> weight;
  std::vector<uint32_t> touched;
};

Scratch& ThreadScratch(size_t point_count) {
  thread_local Scratch scratch;
  if (scratch.weight.size() < point_count) scratch.weight.assign(point_count, 0.0f);
  return scratch;
}

}  // namespace

void LocalizabilityOptions::Check() const {
  VISLOC_CHECK(cell_m > 0.0, "localizability cell ", cell_m, " m: must be positive");
  VISLOC_CHECK(headings >= 1 && headings <= 72, "localizability headings ", headings, ": 1 to 72");
  VISLOC_CHECK(margin_m >= 0.0, "localizability margin ", margin_m, " m");
  VISLOC_CHECK(min_kernel > 0.0 && min_kernel < 1.0, "localizability min_kernel ", min_kernel);
  VISLOC_CHECK(matchable_fraction > 0.0 && matchable_fraction <= 1.0,
               "localizability matchable_fraction ", matchable_fraction);
  VISLOC_CHECK(keypoint_sigma_px > 0.0, "localizability keypoint sigma ", keypoint_sigma_px);
  VISLOC_CHECK(!pitch_deg || std::abs(*pitch_deg) < 90.0, "camera pitch ", *pitch_deg,
               " degrees: must be within (-90, 90)");
}

Rigid3d LevelCameraPose(const Eigen::Vector3d& position, double heading_rad, double pitch_rad) {
  const Eigen::Vector3d forward(std::cos(heading_rad) * std::cos(pitch_rad),
                                std::sin(heading_rad) * std::cos(pitch_rad), -std::sin(pitch_rad));
  const Eigen::Vector3d right =
      Eigen::Vector3d(std::sin(heading_rad), -std::cos(heading_rad), 0.0);  // forward x up, level.
  Eigen::Matrix3d site_from_cam_rotation;
  site_from_cam_rotation.col(0) = right;
  site_from_cam_rotation.col(1) = forward.cross(right);  // Down, in the image's y.
  site_from_cam_rotation.col(2) = forward;
  return Rigid3d(site_from_cam_rotation, position);
}

Eigen::Vector2d LocalizabilityGrid::CellCenter(int ix, int iy) const {
  return {min_x_m + (ix + 0.5) * cell_m, min_y_m + (iy + 0.5) * cell_m};
}

Rigid3d LocalizabilityGrid::SiteFromCam(int ix, int iy, int heading) const {
  const Eigen::Vector2d xy = CellCenter(ix, iy);
  return LevelCameraPose({xy.x(), xy.y(), height_m}, heading_deg(heading) * M_PI / 180.0,
                         pitch_deg * M_PI / 180.0);
}

bool LocalizabilityGrid::Locate(const Rigid3d& site_from_cam, int* ix, int* iy,
                                int* heading) const {
  const Eigen::Vector3d& c = site_from_cam.translation;
  *ix = static_cast<int>(std::floor((c.x() - min_x_m) / cell_m));
  *iy = static_cast<int>(std::floor((c.y() - min_y_m) / cell_m));
  const Eigen::Vector3d forward = site_from_cam.rotation * Eigen::Vector3d::UnitZ();
  const double heading_rad = std::atan2(forward.y(), forward.x());
  const double step = 2.0 * M_PI / headings;
  *heading = static_cast<int>(std::lround(heading_rad / step)) % headings;
  if (*heading < 0) *heading += headings;
  return *ix >= 0 && *ix < cells_x && *iy >= 0 && *iy < cells_y;
}

LocalizabilityPredictor::LocalizabilityPredictor(const LocalizationMap& map,
                                                 const LocalizabilityOptions& options)
    : map_(map), options_(options) {
  options.Check();
  const VisibilityKernel& kernel = map.map().kernel;
  VISLOC_CHECK(kernel.metric.rows() == 2 && kernel.cues == KernelCueNames(),
               "the map has no visibility kernel over the cues this visloc uses");
  // k = exp(-|A d|) <= exp(-sigma_min(A) |d|) <= exp(-sigma_min(A) distance): beyond reach_m_
  // no keyframe can reach min_kernel, whatever its view.
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(kernel.metric);
  const double sigma_min = svd.singularValues().minCoeff();
  reach_m_ = sigma_min > 1e-9 ? std::log(1.0 / options.min_kernel) / sigma_min
                              : std::numeric_limits<double>::infinity();
  const Camera& camera = map.map().camera;
  max_inliers_ = options.max_inliers_per_100k_px > 0
                     ? options.max_inliers_per_100k_px * camera.width() * camera.height() / 1e5
                     : std::numeric_limits<double>::infinity();
  keyframes_by_x_.resize(map.keyframe_count());
  for (size_t i = 0; i < keyframes_by_x_.size(); ++i) keyframes_by_x_[i] = static_cast<int>(i);
  const auto& centers = map.keyframe_centers();
  std::sort(keyframes_by_x_.begin(), keyframes_by_x_.end(),
            [&](int a, int b) { return centers[a].x() < centers[b].x(); });
  for (int i : keyframes_by_x_) sorted_x_.push_back(centers[i].x());
}

void LocalizabilityPredictor::SimilarKeyframes(const Rigid3d& map_from_cam,
                                               std::vector<std::pair<int, double>>* similar) const {
  similar->clear();
  const Eigen::Vector3d center = map_from_cam.translation;
  const Eigen::Vector3d view = map_from_cam.rotation * Eigen::Vector3d::UnitZ();
  const auto& centers = map_.keyframe_centers();
  const auto first = std::lower_bound(sorted_x_.begin(), sorted_x_.end(), center.x() - reach_m_);
  const auto last = std::upper_bound(first, sorted_x_.end(), center.x() + reach_m_);
  const Eigen::MatrixXd& metric = map_.map().kernel.metric;
  for (auto it = first; it != last; ++it) {
    const int i = keyframes_by_x_[it - sorted_x_.begin()];
    if ((centers[i] - center).squaredNorm() > reach_m_ * reach_m_) continue;
    const double k =
        EvaluateKernel(metric, KernelCues(center, view, centers[i], map_.keyframe_view_dirs()[i]));
    if (k >= options_.min_kernel) similar->emplace_back(i, k);
  }
}

LocalizabilityEstimate LocalizabilityPredictor::Predict(const Rigid3d& map_from_cam) const {
  LocalizabilityEstimate estimate = Estimate(map_from_cam);
  estimate.good = IsGood(estimate);
  return estimate;
}

LocalizabilityEstimate LocalizabilityPredictor::Estimate(const Rigid3d& map_from_cam) const {
  thread_local std::vector<std::pair<int, double>> similar;
  SimilarKeyframes(map_from_cam, &similar);
  LocalizabilityEstimate estimate;
  estimate.position_sigma_m = std::numeric_limits<float>::infinity();
  if (similar.empty()) return estimate;

  Scratch& scratch = ThreadScratch(map_.point_count());
  scratch.touched.clear();
  for (const auto& [keyframe, k] : similar) {
    for (uint32_t point : map_.VisiblePoints(keyframe)) {
      float& w = scratch.weight[point];
      if (w == 0.0f) scratch.touched.push_back(point);
      w = std::max(w, static_cast<float>(k));
    }
  }

  const Camera& camera = map_.map().camera;
  const Rigid3d cam_from_map = map_from_cam.Inverse();
  const Eigen::Matrix3d cam_from_map_rotation = cam_from_map.rotation.toRotationMatrix();
  const Eigen::Vector3d center = map_from_cam.translation;
  const double focal = std::sqrt(camera.fx() * camera.fy());
  const double keypoint_var = options_.keypoint_sigma_px * options_.keypoint_sigma_px;
  PointView points;
  try {
    points = map_.Points(scratch.touched);
  } catch (...) {  // A paged map's chunk could not be read: leave the scratch clean.
    for (uint32_t id : scratch.touched) scratch.weight[id] = 0.0f;
    throw;
  }
  // Over (centre in map, rotation in map), m and rad: the keypoints' information, and the
  // points' own errors as the least-squares pose follows them (the tracker's sandwich,
  // PoseTracker::PointsCovariance).
  Matrix6d information = Matrix6d::Zero();
  Matrix6d point_spread = Matrix6d::Zero();
  double visible = 0.0, depth_sum = 0.0;
  for (uint32_t id : scratch.touched) {
    const double w = scratch.weight[id];
    scratch.weight[id] = 0.0f;
    const Eigen::Vector3d& point_in_map = points.position(id);
    const Eigen::Vector3d p = cam_from_map * point_in_map;
    Eigen::Vector2d pixel;
    if (p.z() <= 0.0 || !camera.Project(p, &pixel) || !camera.IsInImage(pixel)) continue;
    visible += w;
    depth_sum += w * p.z();
    // Pinhole at the map camera's mean focal length: the lens's local scale changes the
    // information by a few percent, not where a pose is poor.
    Eigen::Matrix<double, 2, 3> d_pixel_d_cam;
    d_pixel_d_cam << focal / p.z(), 0, -focal * p.x() / (p.z() * p.z()), 0, focal / p.z(),
        -focal * p.y() / (p.z() * p.z());
    const Eigen::Matrix<double, 2, 3> d_pixel_d_map = d_pixel_d_cam * cam_from_map_rotation;
    Matrix26d jacobian;  // Pixel against the camera's centre and a rotation of the camera.
    jacobian.leftCols<3>() = -d_pixel_d_map;
    jacobian.rightCols<3>() = d_pixel_d_map * Skew(Eigen::Vector3d(point_in_map - center));
    information.noalias() += (w / keypoint_var) * jacobian.transpose() * jacobian;
    if (const PointCovariance* cov = points.covariance(id)) {
      const Eigen::Matrix2d pixel_cov = d_pixel_d_map * Unpack(*cov) * d_pixel_d_map.transpose();
      point_spread.noalias() +=
          (w / (keypoint_var * keypoint_var)) * jacobian.transpose() * pixel_cov * jacobian;
    }
  }
  estimate.visible_points = static_cast<float>(visible);
  estimate.expected_inliers = static_cast<float>(ExpectedInliers(visible));
  if (estimate.expected_inliers < 3.0) return estimate;
  // The inliers are a share of the points in view: both sums scale with it.
  const double share = estimate.expected_inliers / visible;
  information *= share;
  point_spread *= share;
  const Eigen::SelfAdjointEigenSolver<Matrix6d> info_eigen(information);
  if (info_eigen.eigenvalues().minCoeff() <= 1e-9 * info_eigen.eigenvalues().maxCoeff()) {
    return estimate;
  }
  const Matrix6d keypoint_cov = information.inverse();
  const Matrix6d point_cov = keypoint_cov * point_spread * keypoint_cov;
  const Matrix6d map_and_rig = MapAndRigCovariance(options_.tracker, map_.map().metadata,
                                                   camera.fx(), depth_sum / visible, center.norm());
  const double rest_variance = (keypoint_cov + map_and_rig).topLeftCorner<3, 3>().trace();
  estimate.point_variance_ratio =
      static_cast<float>(point_cov.topLeftCorner<3, 3>().trace() / rest_variance);
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> position(
      (keypoint_cov + point_cov + map_and_rig).topLeftCorner<3, 3>());
  estimate.position_sigma_m =
      static_cast<float>(std::sqrt(std::max(0.0, position.eigenvalues().maxCoeff())));
  return estimate;
}

double LocalizabilityPredictor::ExpectedInliers(double visible_points) const {
  const double matchable = visible_points * options_.matchable_fraction;
  if (!std::isfinite(max_inliers_)) return matchable;
  // Saturating, not clipped: the frame's keypoints are shared out over the image, so each further
  // point in view finds a free keypoint less often, and the inliers approach the cap without
  // reaching it. (Clipped, every pose beyond the cap tied, and the walks' rankings lost them.)
  return max_inliers_ * (1.0 - std::exp(-matchable / max_inliers_));
}

bool LocalizabilityPredictor::IsGood(const LocalizabilityEstimate& estimate) const {
  return estimate.expected_inliers >= options_.good_inliers &&
         estimate.point_variance_ratio <= options_.max_point_variance_ratio &&
         estimate.position_sigma_m <= options_.good_sigma_m;
}

LocalizabilityGrid ComputeLocalizability(const LocalizationMap& map, const Rigid3d& site_from_map,
                                         const LocalizabilityOptions& options,
                                         LocalizabilityStats* stats) {
  const Timer timer;
  const LocalizabilityPredictor predictor(map, options);
  VISLOC_CHECK(map.keyframe_count() > 0, "the map has no keyframes");
  LocalizabilityGrid grid;
  grid.site_from_map = site_from_map;
  grid.cell_m = options.cell_m;
  grid.headings = options.headings;

  Eigen::AlignedBox2d extent;
  std::vector<double> heights, pitches;
  for (const Keyframe& keyframe : map.map().keyframes) {
    const Rigid3d site_from_cam = site_from_map * keyframe.map_from_cam;
    extent.extend(site_from_cam.translation.head<2>());
    heights.push_back(site_from_cam.translation.z());
    const Eigen::Vector3d forward = site_from_cam.rotation * Eigen::Vector3d::UnitZ();
    pitches.push_back(std::asin(std::clamp(-forward.z(), -1.0, 1.0)) * 180.0 / M_PI);
  }
  grid.height_m = options.height_m.value_or(Median(heights));
  grid.pitch_deg = options.pitch_deg.value_or(Median(pitches));
  grid.min_x_m = extent.min().x() - options.margin_m;
  grid.min_y_m = extent.min().y() - options.margin_m;
  grid.cells_x = std::max(
      1, static_cast<int>(std::ceil((extent.sizes().x() + 2 * options.margin_m) / options.cell_m)));
  grid.cells_y = std::max(
      1, static_cast<int>(std::ceil((extent.sizes().y() + 2 * options.margin_m) / options.cell_m)));
  const int64_t poses_wanted = int64_t{grid.cells_x} * grid.cells_y * grid.headings;
  if (options.max_poses > 0 && poses_wanted > options.max_poses) {
    throw InputError(StrCat("a localizability grid of ", grid.cells_x, " x ", grid.cells_y,
                            " cells of ", options.cell_m, " m and ", grid.headings, " headings is ",
                            poses_wanted, " poses, more than ", options.max_poses,
                            ": take larger cells or fewer headings"));
  }
  const int poses = static_cast<int>(poses_wanted);
  grid.estimates.resize(poses);

  const Rigid3d map_from_site = site_from_map.Inverse();
  ParallelChunks(poses, ResolveThreads(options.threads), 64, [&](int begin, int end) {
    for (int i = begin; i < end; ++i) {
      const int heading = i % grid.headings;
      const int cell = i / grid.headings;
      grid.estimates[i] = predictor.Predict(
          map_from_site * grid.SiteFromCam(cell % grid.cells_x, cell / grid.cells_x, heading));
    }
  });
  if (stats) {
    stats->poses = poses;
    stats->good_poses =
        static_cast<int>(std::count_if(grid.estimates.begin(), grid.estimates.end(),
                                       [](const LocalizabilityEstimate& e) { return e.good; }));
    stats->keyframes = static_cast<int>(map.keyframe_count());
    stats->seconds = timer.ElapsedMs() / 1000.0;
  }
  return grid;
}

}  // namespace visloc
