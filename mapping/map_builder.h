#pragma once
// Builds a map from a stereo sequence (seed paper 000, sec. 3-4):
//
//   per frame:   features (raw images) -> stereo matches + triangulation (rectified) ->
//                tracking: project the recent landmarks with a constant-velocity prediction,
//                match descriptors within a radius, PnP RANSAC + LM on the stereo reprojection
//                error -> keyframe when translation or rotation since the last exceeds the
//                thresholds (paper: 0.15 m, 5 deg) or tracking weakens -> new landmarks from
//                unmatched stereo points -> local BA over the last N_k keyframes, the last n_k
//                free (paper: 10 and 3) -> loop closure against old keyframes near the pose.
//   at the end:  global BA, culling, visibility learning, vocabulary and keyframe vectors,
//                and the map in the map frame (the raw left camera of the first frame).

#include <functional>
#include <string>
#include <vector>

#include "core/camera/stereo_rectifier.h"
#include "core/features/features.h"
#include "core/geometry/trajectory.h"
#include "dataset/dataset.h"
#include "mapping/bundle_adjustment.h"
#include "mapping/slam_state.h"
#include "mapping/stereo_frame.h"
#include "mapping/visibility_learning.h"
#include "mapping/vocabulary_builder.h"

namespace visloc::mapping {

struct MapBuilderOptions {
  FeatureSettings features = DefaultFeatureSettings("harris_surf16");
  StereoMatchOptions stereo;
  double search_radius_px = 15.0;  // Paper: 15 px at 320x240; scaled with image width.
  float match_ratio = 0.85f;
  double keyframe_translation_m = 0.15;
  double keyframe_rotation_deg = 5.0;
  int keyframe_min_tracked = 60;    // Fewer tracked inliers also make a keyframe.
  double track_max_error_px = 2.0;  // A landmark match must reproject this close to be tracked.
  int local_window = 10;            // N_k
  int local_free = 3;               // n_k
  BundleAdjustmentOptions local_ba;
  bool loop_closure = true;
  double loop_radius_m = 0.7;
  double loop_max_angle_deg = 35.0;
  int loop_min_keyframe_gap = 15;
  int loop_min_inliers = 25;
  int loop_cooldown_keyframes = 5;  // After a closure, the next few keyframes see the same loop.
  // A closure whose pose correction (the current keyframe's pose from the old landmarks against
  // its tracked pose) reaches either bound re-adjusts every keyframe at once.
  double loop_adjust_min_correction_m = 0.05;
  double loop_adjust_min_correction_deg = 1.0;
  int global_ba_iterations = 40;
  int min_point_observations = 2;  // Landmarks seen by fewer keyframes are left out.
  VisibilityLearningOptions visibility;
  VocabularyOptions vocabulary;
  void Check() const;
};

struct MapBuildStats {
  int frames = 0;
  int tracking_failures = 0;
  int keyframes = 0;
  int points = 0;
  int observations = 0;
  int loop_closures = 0;
  int loop_adjustments = 0;           // Closures large enough to re-adjust every keyframe at once.
  double reprojection_rmse_px = 0.0;  // Left image, after global BA.
  double disparity_rmse_px = 0.0;     // Predicted vs measured disparity, after global BA.
  VisibilityLearningStats visibility;
  double features_ms = 0, tracking_ms = 0, local_ba_ms = 0, loop_ms = 0, global_ba_ms = 0,
         learning_ms = 0, total_ms = 0;
};

class MapBuilder {
 public:
  MapBuilder(const CameraInfo& left, const CameraInfo& right, const MapBuilderOptions& options);

  // Processes one stereo frame (raw 8-bit grey images of the calibrated size).
  void AddFrame(int64_t timestamp_ns, const cv::Mat& left_raw, const cv::Mat& right_raw);
  // Global BA, culling, learning and assembly. Call once, after the last frame.
  Map Finish(const MapMetadata& metadata);

  const MapBuildStats& stats() const { return stats_; }
  // The raw left camera's estimated pose per processed frame, in the map frame.
  Trajectory FrameTrajectory() const;
  // Short status for progress displays.
  std::string Status() const;

 private:
  struct Match {
    int landmark;
    int feature;
  };
  std::vector<Match> MatchLandmarks(const StereoFrame& frame, const Rigid3d& cam_from_world,
                                    const std::vector<int>& landmarks, double radius_px) const;
  void AddKeyframe(int64_t timestamp_ns, StereoFrame&& frame, const Rigid3d& cam_from_world,
                   const std::vector<Match>& tracked);
  void LocalBundleAdjust();
  void TryLoopClosure();
  std::vector<int> RecentLandmarks() const;
  Rigid3d MapFromWorld() const;

  CameraInfo left_;
  MapBuilderOptions options_;
  StereoRectifier rectifier_;
  RectifiedIntrinsics intrinsics_;
  std::unique_ptr<FeatureExtractor> extractor_;
  SlamState state_;
  Trajectory frame_cam_from_world_;  // Rectified left camera, world frame (tracking estimate).
  // Each frame's pose relative to the keyframe it was tracked from, so that later keyframe
  // corrections (BA, loop closure) carry over to the frame trajectory.
  std::vector<std::pair<int, Rigid3d>> frame_from_keyframe_;
  int keyframes_since_loop_ = 1000;
  Rigid3d velocity_;  // cam_from_world(t) * cam_from_world(t-1)^-1
  MapBuildStats stats_;
  int last_tracked_ = 0;
};

// Builds a map from every frame of a stereo dataset. `progress(done, total, status)` is called
// per frame. Throws InputError for monocular datasets or unreadable images.
Map BuildMap(const Dataset& dataset, const MapBuilderOptions& options, const MapMetadata& metadata,
             MapBuildStats* stats, Trajectory* frame_trajectory = nullptr,
             const std::function<void(int, int, const std::string&)>& progress = nullptr);

}  // namespace visloc::mapping
