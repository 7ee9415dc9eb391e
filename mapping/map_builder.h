#pragma once
// Builds a map from a stereo sequence (seed paper 000, sec. 3-4), one frame at a time:
//
//   per frame:   features (raw images) -> stereo matches + triangulation (stereo_frame.h) ->
//                tracking against the recent landmarks (frame_tracker.h) -> keyframe when the
//                camera moved, turned or tracking weakened; its untracked stereo points become
//                landmarks (keyframes.h) -> local BA over the last N_k keyframes, the last n_k
//                free (paper: 10 and 3) -> loop closure against old keyframes near the pose
//                (loop_closure.h).
//   at the end:  global BA, then the map in the map frame with its visibility kernel and
//                vocabulary (map_assembly.h).
//
// The builder takes frames, not datasets: dataset_mapping.h feeds it a recorded sequence.

#include <memory>
#include <string>

#include "core/camera/stereo_rectifier.h"
#include "core/features/features.h"
#include "core/geometry/trajectory.h"
#include "core/map/map.h"
#include "mapping/bundle_adjustment.h"
#include "mapping/frame_tracker.h"
#include "mapping/keyframes.h"
#include "mapping/loop_closure.h"
#include "mapping/map_assembly.h"
#include "mapping/slam_state.h"
#include "mapping/stereo_frame.h"

namespace visloc::mapping {

struct MapBuilderOptions {
  FeatureSettings features = DefaultFeatureSettings("harris_surf16");
  // features' max_features is the count at 320x240, scaled to the images (FeatureCountForImage);
  // false keeps it as given.
  bool scale_feature_count = true;
  StereoMatchOptions stereo;
  TrackingOptions tracking;
  KeyframeOptions keyframes;
  BundleAdjustmentOptions local_ba;
  LoopClosureOptions loop_closure;
  int global_ba_iterations = 40;
  AssemblyOptions assembly;
  void Check() const;  // Checks every nested options struct too.
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
  // The calibrated pair: raw cameras and the right camera's pose from the left one.
  MapBuilder(const Camera& left, const Camera& right, const Rigid3d& right_from_left,
             const MapBuilderOptions& options);

  // Processes one stereo frame (raw 8-bit grey images of the calibrated size).
  void AddFrame(int64_t timestamp_ns, const cv::Mat& left_raw, const cv::Mat& right_raw);
  // Global BA, then the map. Call once, after the last frame.
  Map Finish(const MapMetadata& metadata);

  const MapBuildStats& stats() const { return stats_; }
  // The raw left camera's estimated pose per processed frame, in the map frame.
  Trajectory FrameTrajectory() const;
  // Short status for progress displays.
  std::string Status() const;

 private:
  void StartKeyframe(int64_t timestamp_ns, StereoFrame&& frame, const Rigid3d& cam_from_world,
                     const std::vector<LandmarkMatch>& tracked);
  Rigid3d MapFromWorld() const;
  Rigid3d RectFromRaw() const;

  Camera left_;
  MapBuilderOptions options_;
  StereoRectifier rectifier_;
  RectifiedIntrinsics intrinsics_;
  std::unique_ptr<FeatureExtractor> extractor_;
  FrameTracker tracker_;
  LoopCloser loop_closer_;
  SlamState state_;
  // Each frame's pose relative to the keyframe it was tracked from, so that later keyframe
  // corrections (BA, loop closure) carry over to the frame trajectory.
  std::vector<int64_t> frame_timestamps_ns_;
  std::vector<std::pair<int, Rigid3d>> frame_from_keyframe_;
  Rigid3d last_cam_from_world_;
  Rigid3d velocity_;  // cam_from_world(t) * cam_from_world(t-1)^-1
  MapBuildStats stats_;
  int last_tracked_ = 0;
};

}  // namespace visloc::mapping
