#pragma once
// What a localization session is tuned by: the tracker, relocalization, the motion filter and
// the status thresholds. Pixel radii are given at 320 pixels of image width (QueryPipeline scales
// them to the camera).

#include "core/localization/pose_tracker.h"
#include "core/localization/relocalizer.h"

namespace visloc {

struct MotionOptions {
  // Constant-velocity model: process noise per second (walking changes speed every step).
  double velocity_sigma_mps = 0.3;
  double velocity_sigma_degps = 15.0;
  // Odometry: noise proportional to the motion, plus a floor per frame.
  double odometry_translation_fraction = 0.08;
  double odometry_rotation_fraction = 0.08;
  double odometry_floor_m = 0.003;
  double odometry_floor_deg = 0.3;
  // Gyro: angle random walk (rad / sqrt(s)), plus bias uncertainty (rad / s).
  double gyro_noise_rad_sqrt_s = 2e-3;
  double gyro_bias_radps = 5e-3;
  // Bridging frames without a visual fix.
  double max_bridge_s = 3.0;
  double max_bridge_sigma_m = 0.5;
  bool bridge_with_constant_velocity = false;  // Only for comparison with vision alone.
  // Without a velocity (no recent fixes) the constant-velocity noise is this many times larger.
  double unknown_velocity_noise_scale = 2.0;
  // Planar motion: the camera stays `height_m` above the plane of the map's keyframes (a
  // walking robot's head), with this standard deviation. 0 disables it.
  double plane_sigma_m = 0.0;
  double height_m = 0.0;
  // The keyframes span a plane when there are this many, spread at least plane_min_spread_m in
  // two directions (standard deviation) and at most plane_max_flatness of that in the third.
  int plane_min_keyframes = 6;
  double plane_min_spread_m = 0.3;
  double plane_max_flatness = 0.1;
};

struct LocalizerOptions {
  PoseTrackerOptions tracker;
  RelocalizationOptions relocalization;
  MotionOptions motion;
  // Support needed for each status.
  int min_tracking_inliers = 30;
  double min_tracking_inlier_ratio = 0.4;
  int min_limited_inliers = 12;
  // A tracked fix whose inlier points' own uncertainty is more than this share of its position
  // variance over the rest (PoseFix::point_variance_ratio) is limited, not tracking: it leans on
  // points the map saw from elsewhere, and its sigma says so.
  double max_tracking_point_variance_ratio = 1.0;
  // Jump gate: a fix further than this (plus jump_gate_sigmas of the prior's position sigma)
  // from the prior needs confirmation (fix_policy.h).
  double max_jump_m = 0.2;
  double max_jump_deg = 10.0;
  double jump_gate_sigmas = 3.0;
  // While the motion is known, a tracked fix must also agree with the filter's prediction: the
  // squared Mahalanobis distance of their difference, in the prediction's covariance plus the
  // fix's noise, at most this (chi-square, 6 degrees of freedom, 0.999). A fix from a few
  // points on one side of a half-covered image can be 10 cm and 4 degrees off and well within
  // the jump gate; it is held for the next frame to confirm instead of reported tracking.
  // Measured: tracked fixes of the rendered sequences, EuRoC MH_01 and KITTI 01 (once its
  // velocity is known) reach at most 4.3.
  double max_innovation_chi2 = 22.46;
  // The velocity is the motion between two fixes at most this far apart (s).
  double velocity_window_s = 0.5;
  // Local relocalization searches keyframes within this of the last pose, while lost for less
  // than local_relocalization_s.
  double local_radius_m = 1.0;
  double local_relocalization_s = 2.0;
  // Radii given at 320 pixels of image width, scaled with the session camera's width.
  bool scale_radii_with_width = true;
  // Keypoints per query image; 0 keeps the map's setting. The detector and descriptor are
  // always the map's; only how many of the strongest (evenly spread) corners are kept changes.
  // The paper's 600 at any resolution: maps of larger images hold more corners per keyframe
  // (FeatureCountForImage), but a fix from the 160 best predicted points and the tight
  // re-matching needs no more query corners, and each costs description and matching time
  // (EuRoC 752x480: 2.0 ms a frame with 600, 2.4 ms with the map's 1300, the same spread).
  int max_query_features = 600;
  // A rig's images of one frame are taken at the same moment: their stamps may differ from the
  // reference camera's by at most this (a hardware-triggered rig's are equal; 5 ms is a frame
  // of a 200 Hz camera, and a robot turning at 1 rad/s moves 5 mrad in it).
  int64_t max_rig_skew_ns = 5'000'000;
  // A rig's cameras are worked on side by side on up to this many threads (features, then each
  // camera's prediction and search): a frame's latency, not its CPU time, shrinks. The answers
  // are the same for any count. A server sets its worker count.
  int rig_threads = 1;
  // The rig's helper threads wake themselves just before the next frame is due, by the rhythm
  // of the frames so far (ArrivalPredictor), and look for it over a window of the arrivals'
  // jitter (0.3-3 ms a side) instead of sleeping until it comes: a sleeping thread on an idle
  // virtual core starts 0.1-0.2 ms after it is woken. false: they sleep between frames.
  bool rig_wake_ahead = true;
  // Detect query corners at the map detector's finest scale only (as the seed paper does for
  // speed); false uses all of the map's scales.
  bool finest_scale_only = true;
  // Keypoints per image for relocalization, detected at all of the map's scales; 0 keeps the
  // map's own count. Without a prior, descriptors alone must find the map's points, and a point
  // is found only where the query detects its corner again at the scale the map described it
  // at. Measured on real images (EuRoC MH_01, a map of frames 0-74, each of frames 75-149
  // alone): among the ~500 points a candidate keyframe sees, 40-75 had a keypoint of the
  // 600-corner finest-scale query within 2.5 px of their true projection and ~10 a correct
  // descriptor match, too few for RANSAC among ~100 matches (61 of 75 found); with the map's
  // 1300 corners at all scales, 80-150 and 25-40 (71 of 75, and 75 of 75 with the RANSAC budget
  // below). Tracking keeps the cheaper query features: its prior finds the points by position.
  int max_relocalization_features = 0;
  // Relocalize with the tracking features first (the finest scale, max_query_features) and with
  // those above only when that verifies no candidate. A view close to a keyframe's is found with
  // the cheap features, at half the cost of extracting at every scale; the views they miss (the
  // comment above) get the full features next, so recall is that of the full features alone.
  // The acceptance test (verified inliers and ratio) is the same for both passes, and a
  // session's first frame is relocalized as the Relocalize RPC relocalizes its image. A session
  // whose last relocalization found nothing with either (out of the map, camera covered) goes
  // to the full features directly until it is found, so a robot that stays lost pays one pass.
  bool relocalize_with_tracking_features_first = true;
  // A query camera whose focal length differs from the map camera's by more than this factor
  // (either way) has its images resampled to the map's focal length before detection. The
  // detector's scales are in pixels, so without it a corner the map described at one scale is
  // described at another in the query. A 640x480 camera in a map made at 320x240 (same field of
  // view): relocalization matched half the points and its bag of words ranked every keyframe
  // alike (0.47-0.49), so the right place could miss the candidates; tracking kept 56% of its
  // matches as inliers (97% at 320x240) and was 1.6 cm off at the median (0.33 cm).
  double resample_ratio = 1.2;
  void Check() const;
};

}  // namespace visloc
