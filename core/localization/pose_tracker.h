#pragma once
// Visibility-guided pose estimation from a prior (seed paper 000, sec. 5): predict the map
// points visible from the prior pose, project them, match descriptors in a radius around each
// projection, solve PnP with RANSAC, then re-match in a tight radius around the projections of
// the RANSAC pose and refine with Levenberg-Marquardt on the inliers (eq. 9).
//
// Not thread-safe (the visibility predictor keeps scratch space); one per session.

#include <array>
#include <memory>
#include <vector>

#include "core/camera/camera.h"
#include "core/estimators/pnp_ransac.h"
#include "core/localization/map_matching.h"
#include "core/localization/query_frame.h"
#include "core/localization/visibility_predictor.h"
#include "core/map/localization_map.h"

namespace visloc {

// Which map points a prior pose predicts: the paper's learned visibility, or the baselines.
enum class PredictionMode {
  kVisibility,   // Learned visibility kernel (eq. 8).
  kTransparent,  // Every point in front of the camera that projects into the image.
  kBruteForce,   // No prior: all keypoints against all map descriptors.
};
const char* PredictionModeName(PredictionMode mode);
// "visibility", "transparent" or "brute_force"; throws InputError otherwise.
PredictionMode ParsePredictionMode(const std::string& name);

struct PoseTrackerOptions {
  PredictionMode prediction = PredictionMode::kVisibility;
  VisibilityOptions visibility;
  double search_radius_px = 15.0;  // Guided search radius (paper: 15 px at 320x240).
  DescriptorMatchOptions matching;
  double refine_radius_px = 4.0;  // Tight re-matching radius around the RANSAC pose.
  // Points matched in the wide radius for RANSAC: the most probably visible, spread over the
  // image (0: all). A RANSAC pose from a couple of hundred matches is as good as from all of
  // them once every predicted point is re-matched around it in the tight radius, and the wide
  // search is most of the matching time. When RANSAC fails on the subset, all points are tried.
  // A rig shares them among its cameras that have an image (at least rig_min_coarse_points
  // each).
  int coarse_points = 160;
  int rig_min_coarse_points = 60;
  PnpRansacOptions ransac;  // max_error_px is also the inlier threshold of the refinement.
  // The map's own error, which a fix inherits from the points it is made of. The keypoint noise
  // of a fix averages out over its inliers and, in a session, over frames; this does not, since
  // every frame that sees the same points sees the same error. A fix's systematic covariance
  // holds, per position axis, in quadrature: map_error_px (at 320 px of width) as an angle at the
  // inliers' median depth, the mapping's absolute registration map_floor_m (none: the map frame
  // is its first keyframe) and its drift, map_drift_fraction of the distance from the map's
  // origin, and the rig calibration's own floor and drift (RigError, core/map/map.h); and
  // map_error_px as an angle for the rotation. The mapping's share is measured where the
  // calibration is exact and the ground truth too: on the rendered query sequences
  // (docs/benchmarks.md) the median error is then 1.1-1.3 of the per-axis sigma, at most 1% of
  // frames beyond 3. A real rig's share, for maps that do not say theirs, is what EuRoC MH_01
  // needs on top (docs/real-world.md: median 1.5, none beyond 3). A map whose calibration is
  // worse than it says (KITTI 01's, off by 1.2% of the distance) is not covered: nothing in the
  // images shows a map scaled as a whole.
  double map_error_px = 0.1;
  double map_floor_m = 0.0;
  double map_drift_fraction = 0.0015;
  double rig_floor_m = 0.0025;
  double rig_drift_fraction = 0.0026;
  // The map points' own uncertainty (point_uncertainty.h), as the frame sees them: each inlier's
  // covariance projected into the image moves the pose as the refinement would follow it, the
  // points' errors independent of each other (what they share, the keyframes' own errors, is
  // map_error_px's and after), times point_error_gain (0 leaves it out). Fully correlated
  // instead, the generated walks' median error fell to 0.1-0.2 sigma: far too wide. Maps that
  // do not know their points' uncertainty leave it out.
  double point_error_gain = 1.0;
  // Inliers whose covariances are summed (an even sample, scaled to all; 0: every one).
  int covariance_points = 160;
  // A rig's camera takes part in the joint fix only while its inliers are significant against
  // chance (ChanceInliersNegLog10 over its tight re-matches, -log10): a covered or blinded
  // camera's noise re-matches a quarter of its putatives within the inlier threshold by chance
  // (generated kidnap, front camera covered: 20-34 of 82-117, significance below 3), which
  // pulled the rear camera's fix 2.6 cm off at 7.7 sigma. A camera seeing the map scores in the
  // tens to hundreds.
  double rig_camera_min_significance = 8.0;
  void Check() const;
};

struct PoseStepTimes {
  double predict_ms = 0.0;
  double project_ms = 0.0;
  double match_ms = 0.0;
  double pose_ms = 0.0;
};

struct PoseFix {
  bool success = false;
  Rigid3d cam_from_map;
  // Translation (m) then rotation (rad): from the keypoints' noise (the refinement's, scaled by
  // the measured reprojection error), and from the map's own error (map_error_px), which
  // fusing fixes does not reduce. TotalCovariance() is their sum.
  Eigen::Matrix<double, 6, 6> covariance = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix<double, 6, 6> systematic_covariance = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix<double, 6, 6> TotalCovariance() const { return covariance + systematic_covariance; }
  int predicted = 0;          // Points predicted visible.
  int putatives = 0;          // Matches after the final (tight) association.
  int inliers = 0;            // Putatives within the inlier threshold of the final pose.
  double inlier_ratio = 0.0;  // inliers / putatives.
  int ransac_iterations = 0;
  double reproj_rmse_px = 0.0;  // Over the inliers.
  // Cells of a kCoverageCols x kCoverageRows grid over the image that hold an inlier: a fix
  // whose inliers crowd one corner of the image constrains the pose far less than its count says.
  int inlier_cells = 0;
  // The inlier points' own uncertainty (PoseTrackerOptions::point_error_gain) in the position's
  // variance, over the rest of it (the keypoints' noise and the map's and rig's error): above 1,
  // the fix leans on points the map knows poorly from where this frame sees them. Measured: at
  // most 0.41 on the generated walks the mapping run made; up to 2.6 facing out of the mapped
  // square, up to 6 glancing over the shoulder.
  double point_variance_ratio = 0.0;
  static constexpr int kCoverageCols = 8;
  static constexpr int kCoverageRows = 6;
  PoseStepTimes times;
  // A rig's fix (rig_tracker.h): each camera's share, in the rig's order; empty for one camera.
  struct CameraSupport {
    int features = 0;
    int predicted = 0;
    int putatives = 0;
    int inliers = 0;
  };
  std::vector<CameraSupport> cameras;
};

// The inlier points' own uncertainty moved into a camera's pose (PoseTrackerOptions::
// point_error_gain) before it becomes a covariance: the upper triangle of sum J^T Omega J (row by
// row) over an even sample of the inliers, and the sample's scale to all of them.
struct PointSpread {
  std::array<double, 21> upper{};
  double to_all = 1.0;
  bool unknown = false;  // A point without a covariance: the map does not know them.
  Eigen::Matrix<double, 6, 6> Matrix() const;  // Not scaled by to_all.
};

// The map's and the rig calibration's share of a fix's covariance (PoseTrackerOptions::
// map_error_px and after; the map's recorded rig error, when it has one) for a camera of focal
// length `focal_px`, its inliers at `median_depth_m`, `from_origin_m` from the map's origin.
Eigen::Matrix<double, 6, 6> MapAndRigCovariance(const PoseTrackerOptions& options,
                                                const MapMetadata& metadata, double focal_px,
                                                double median_depth_m, double from_origin_m);

class PoseTracker {
 public:
  PoseTracker(std::shared_ptr<const LocalizationMap> map, const Camera& camera,
              const PoseTrackerOptions& options);

  // Full guided estimation from a prior pose.
  PoseFix Track(const QueryFrame& frame, const Rigid3d& prior_cam_from_map) const;
  // Verification and refinement of a pose from elsewhere (relocalization's RANSAC on
  // descriptor matches), as Track ends: predict the points visible from it, re-match them in the
  // tight radius and refine on the inliers. The refinement starts from the inliers within the
  // RANSAC threshold of the given pose, so a pose further off than that is not verified.
  PoseFix Polish(const QueryFrame& frame, const Rigid3d& cam_from_map) const;

  const PoseTrackerOptions& options() const { return options_; }
  const Camera& camera() const { return camera_; }

  // The stages of Track, for a rig's tracker (rig_tracker.h) that runs them per camera.
  // The points predicted visible from `cam_from_map` (count and time into `fix`).
  std::vector<uint32_t> PredictPoints(const Rigid3d& cam_from_map, PoseFix* fix) const;
  // The projections matched in the wide radius: `projected` itself when it has at most
  // `wanted` (0: all), else that many of them spread over the image, written to `subset`.
  const std::vector<ProjectedPoint>& CoarseSubset(const std::vector<ProjectedPoint>& projected,
                                                  int wanted,
                                                  std::vector<ProjectedPoint>* subset) const;
  // The map's and the rig calibration's share of a fix's covariance (map_error_px and after),
  // for inliers at `median_depth_m`, the camera `from_origin_m` from the map's origin.
  Eigen::Matrix<double, 6, 6> MapAndRigCovariance(double median_depth_m,
                                                  double from_origin_m) const;
  // The inlier points' own uncertainty as this camera sees them at `cam_from_map`, by its own
  // pose's perturbation.
  PointSpread PointSpreadOf(const PointView& map_points, const std::vector<PointMatch>& matches,
                            const std::vector<PoseObservation>& observations,
                            const std::vector<char>& inliers, const Rigid3d& cam_from_map) const;
  // PoseFix::inlier_cells of the inlier `matches` (the mask is per match).
  int InlierCells(const QueryFrame& frame, const std::vector<PointMatch>& matches,
                  const std::vector<char>& inliers) const;
  const LocalizationMap& map() const { return *map_; }
  // Undistorted normalized observations of matched points (all in `map_points`), for the pose
  // solvers.
  std::vector<PoseObservation> Observations(const PointView& map_points, const QueryFrame& frame,
                                            const std::vector<PointMatch>& matches) const;

 private:
  // RANSAC on the matches' observations (one refinement pass), timed into `fix`.
  PnpResult SolveFromMatches(const PointView& map_points, const QueryFrame& frame,
                             const std::vector<PointMatch>& matches, PoseFix* fix) const;
  // A fix's systematic covariance (PoseTrackerOptions::map_error_px and after), from its inlier
  // observations at `cam_from_map`.
  Eigen::Matrix<double, 6, 6> SystematicCovariance(const std::vector<PoseObservation>& observations,
                                                   const std::vector<char>& inliers,
                                                   const Rigid3d& cam_from_map) const;
  // The share of the inlier points' own uncertainty (PoseTrackerOptions::point_error_gain);
  // zero when the map does not know it. `inverse_information` is the refinement's (J^T J)^-1 in
  // normalized units: the pose moves by it times J^T of the points' shifts in the image.
  Eigen::Matrix<double, 6, 6> PointsCovariance(
      const PointView& map_points, const std::vector<PointMatch>& matches,
      const std::vector<PoseObservation>& observations, const std::vector<char>& inliers,
      const Rigid3d& cam_from_map, const Eigen::Matrix<double, 6, 6>& inverse_information) const;
  // The fix's covariances and point_variance_ratio, from its refinement.
  void SetCovariances(const PointView& map_points, const std::vector<PointMatch>& matches,
                      const std::vector<PoseObservation>& observations, const PnpResult& refined,
                      PoseFix* fix) const;
  // Re-matches `points` around their projections from `cam_from_map` in `radius_px` and refines.
  void RefineAround(const PointView& map_points, const QueryFrame& frame,
                    const std::vector<uint32_t>& points, const Rigid3d& cam_from_map,
                    double radius_px, PoseFix* fix) const;

  std::shared_ptr<const LocalizationMap> map_;
  Camera camera_;
  PoseTrackerOptions options_;
  std::unique_ptr<VisibilityPredictor> predictor_;
  std::vector<uint32_t> all_points_;  // For the brute-force baseline.
};

}  // namespace visloc
