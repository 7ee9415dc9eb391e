#pragma once
// Localizability: where in a mapped site a camera will localize, looking which way, predicted
// from the map alone (no images). For a camera at a pose:
//   - which points it will see: each map point weighted by the learned visibility kernel
//     (seed paper 000, eq. 7) of the most similar keyframe that saw it, w_j = max_i k(theta,
//     theta_i) v_j(theta_i). The kernel was fitted to how much keyframes' visible sets overlap, so
//     k(theta, theta_i) reads as the share of keyframe i's points seen from theta. Unlike eq. 8's
//     prediction it is not normalized over the K nearest keyframes: a pose far from every
//     keyframe sees nothing, however its neighbours agree.
//   - in the frustum: the point lies in front of the camera and projects into its image;
//   - matchable: a share of those become inliers (LocalizabilityOptions::matchable_fraction,
//     measured on the generated walks), saturating at what a frame's keypoints can give;
//   - and how well they pin the pose: the Fisher information of the pose from their projections
//     with the keypoints' noise; the points' own uncertainty (point_uncertainty.h) as the pose
//     follows it, and the map's and rig's error, as the tracker counts them (pose_tracker.h). The
//     position sigma is the square root of the largest eigenvalue of the position block of their
//     sum (the localizer's position_sigma_m); a pose whose points' share of it exceeds the rest's
//     leans on points the map saw from elsewhere, which the localizer reports limited.
// The grid lies in a level frame (z up: the map's site frame, map.h SiteFromMap), over the
// keyframes' extent, one camera per cell and heading at the mapping camera's typical height and
// pitch, unless told.

#include <optional>
#include <string>
#include <vector>

#include "core/camera/camera.h"
#include "core/geometry/rigid3.h"
#include "core/localization/pose_tracker.h"
#include "core/map/localization_map.h"

namespace visloc {

struct LocalizabilityOptions {
  double cell_m = 0.5;  // Side of a grid cell (m).
  int headings = 16;    // Per cell, evenly around the site's z from its +x axis.
  // The camera's height (z in the site frame, m) and its pitch below level (degrees); by default
  // the keyframes' medians, the mapping robot's.
  std::optional<double> height_m;
  std::optional<double> pitch_deg;
  double margin_m = 1.0;  // The grid reaches this far beyond the keyframes' extent.
  // Keyframes less similar to the pose than this (kernel value) do not vote: their share of the
  // view is noise, and skipping them keeps a 10,000-keyframe map's grid within a minute.
  double min_kernel = 0.02;
  // The share of points in view that become inliers while few are in view (ExpectedInliers
  // saturates it at the frame's keypoints). Chosen on the square's generated walks, where it best
  // separates the frames the localizer lost or limited from the rest; the prediction then runs
  // 12-15% below the inliers the tracked frames had (docs/localizability.md).
  double matchable_fraction = 0.75;
  // A frame's inliers cannot exceed its keypoints': this many per 100,000 image pixels (the
  // localizer's default 600 at 320x240; 0: no cap). Approached, not clipped (ExpectedInliers).
  double max_inliers_per_100k_px = 780.0;
  // A query keypoint's noise (raw image pixels): the tracker's measured reprojection error on the
  // generated walks (0.38-0.40 px).
  double keypoint_sigma_px = 0.4;
  PoseTrackerOptions tracker;  // The map's and rig's error (map_error_px and after).
  // A pose is predicted good when it expects at least this many inliers (the localizer's
  // min_tracking_inliers), its points' share of the position variance is at most
  // max_point_variance_ratio and its position sigma at most good_sigma_m. The localizer reports
  // limited above a share of 1 (max_tracking_point_variance_ratio) of its inliers' own; the
  // prediction's share, over every point in view rather than those the matcher kept (the nearer,
  // better-known ones), runs higher: on the generated square's walks, frames the localizer
  // reported limited were predicted at 3.7-7.6 and tracked ones mostly below 2.5. Chosen there
  // and checked on another map of the same walks and the real recordings (docs/localizability.md).
  double good_inliers = 30.0;
  double max_point_variance_ratio = 2.5;
  double good_sigma_m = 0.05;
  int threads = 1;  // 0: every core.
  // A grid of more poses (cells times headings) is refused (InputError) before it is computed;
  // 0: no bound. A server bounds what one request may cost and send.
  int max_poses = 0;
  void Check() const;
};

struct LocalizabilityEstimate {
  float expected_inliers = 0.0f;
  // Infinity when the points in view leave the pose unconstrained.
  float position_sigma_m = 0.0f;
  float visible_points = 0.0f;  // Kernel-weighted points in the frustum, before matchability.
  // The points' own uncertainty in the position variance over the rest (PoseFix's).
  float point_variance_ratio = 0.0f;
  bool good = false;  // LocalizabilityOptions::good_inliers and after.
};

struct LocalizabilityGrid {
  Rigid3d site_from_map;
  double min_x_m = 0.0, min_y_m = 0.0;  // The grid's corner in the site frame.
  double cell_m = 0.5;
  int cells_x = 0, cells_y = 0, headings = 0;
  double height_m = 0.0, pitch_deg = 0.0;
  // (iy * cells_x + ix) * headings + h.
  std::vector<LocalizabilityEstimate> estimates;

  const LocalizabilityEstimate& at(int ix, int iy, int heading) const {
    return estimates[(static_cast<size_t>(iy) * cells_x + ix) * headings + heading];
  }
  double heading_deg(int heading) const { return 360.0 * heading / headings; }
  Eigen::Vector2d CellCenter(int ix, int iy) const;
  // The camera of cell (ix, iy) looking along `heading`, site_from_cam.
  Rigid3d SiteFromCam(int ix, int iy, int heading) const;
  // The cell and nearest heading of a camera at site_from_cam; false outside the grid.
  bool Locate(const Rigid3d& site_from_cam, int* ix, int* iy, int* heading) const;
};

struct LocalizabilityStats {
  int poses = 0;       // Cells times headings.
  int good_poses = 0;  // Predicted good (LocalizabilityOptions::good_inliers, good_sigma_m).
  int keyframes = 0;
  double seconds = 0.0;
};

// A map's grid as a server reports it: with the frame it lies in (mapping::PlanFrame).
struct LocalizabilityReport {
  std::string map;
  LocalizabilityGrid grid;
  LocalizabilityStats stats;
  std::string frame;  // "site", "level" or "floor".
  std::string frame_how;
};

// A level camera pose: at `position` (site frame), its optical axis at `heading_rad` about z from
// +x and `pitch_rad` below level; x right, y down (OpenCV). site_from_cam.
Rigid3d LevelCameraPose(const Eigen::Vector3d& position, double heading_rad, double pitch_rad);

class LocalizabilityPredictor {
 public:
  // Throws CheckError when the map has no learned kernel.
  LocalizabilityPredictor(const LocalizationMap& map, const LocalizabilityOptions& options);

  // What a camera (the map's) at `map_from_cam` can expect.
  LocalizabilityEstimate Predict(const Rigid3d& map_from_cam) const;

 private:
  LocalizabilityEstimate Estimate(const Rigid3d& map_from_cam) const;
  bool IsGood(const LocalizabilityEstimate& estimate) const;
  // The inliers `visible_points` kernel-weighted points in the frustum give: their matchable
  // share, saturating at max_inliers_.
  double ExpectedInliers(double visible_points) const;
  // Keyframes whose kernel value for the pose is at least min_kernel, with those values.
  void SimilarKeyframes(const Rigid3d& map_from_cam,
                        std::vector<std::pair<int, double>>* similar) const;

  const LocalizationMap& map_;
  LocalizabilityOptions options_;
  double max_inliers_ = 0.0;
  double reach_m_ = 0.0;             // No keyframe farther than this can reach min_kernel.
  std::vector<int> keyframes_by_x_;  // Keyframe indices sorted by their centre's x (map frame).
  std::vector<double> sorted_x_;
};

// The grid over the map's keyframes in the frame `site_from_map` (z up).
LocalizabilityGrid ComputeLocalizability(const LocalizationMap& map, const Rigid3d& site_from_map,
                                         const LocalizabilityOptions& options,
                                         LocalizabilityStats* stats = nullptr);

}  // namespace visloc
