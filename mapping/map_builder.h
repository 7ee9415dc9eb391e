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
#include <optional>
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

// The rig's disparity correction (core/camera/disparity_correction.h), estimated while mapping.
// What observes it is the parallax the camera's own motion adds to the stereo baseline, so the
// first frames are mapped until the camera has travelled `travel_baselines` stereo baselines
// (KITTI: 48 m; EuRoC: 10 m), or for `max_frames` frames, or to the end of a shorter sequence.
// Then, when it has travelled at least `min_travel_baselines` (less says little: KITTI 00's first
// 7.5 m put the offset at -0.4 px, its first 30 m at -0.6), a bundle adjustment of all their
// keyframes estimates a change of the correction with the poses and points, under priors of the
// given sigmas, and the frames are mapped again with it, until a change moves no disparity by
// `converged_px` or after `max_passes`; later frames are mapped with it. An adjustment goes
// only part of the way (a 0.1 deg yaw in a rendered drive: 0.083 deg first; on KITTI 01 about
// half of what is left each time): the tracks and keyframes it adjusts were made with the old
// correction, and adjusting them again finds no more, so the frames are mapped again.
//
// A rig's correction, once estimated, belongs to the rig (until its mount moves): `known` takes
// one (a previous build's estimate, its stats' disparity_correction) off from the first frame
// instead, so a build maps every frame once, and a recording too short to estimate it from is
// metric too. `enabled` must then be false.
struct DisparityCalibrationOptions {
  // The largest known correction taken (Check): beyond these the rig needs calibrating again,
  // not correcting (5 deg of yaw is 60 px of disparity at KITTI's focal length).
  static constexpr double kMaxKnownOffsetPx = 20.0;
  static constexpr double kMaxKnownYawDeg = 5.0;
  bool enabled = true;
  std::optional<DisparityCorrection> known;
  double travel_baselines = 90.0;
  double min_travel_baselines = 40.0;
  int max_frames = 150;
  int max_passes = 4;
  double converged_px = 0.05;
  double offset_sigma_px = 2.0;
  double yaw_sigma_deg = 0.3;
  // Each pass's adjustment stops once an iteration lowers its cost by less than this fraction
  // (the global adjustment's is Ceres's 1e-6). A pass's estimate is not the last word: the frames
  // are mapped again with it and the next pass measures what is left, until a change falls below
  // converged_px. On KITTI 01 a build's global adjustments (the passes and the final one) then
  // take 560-660 ms instead of 690-740, and builds from its frames 0-4 on end 1.258% of the
  // distance off at the median against 1.260%.
  double function_tolerance = 1e-3;
  void Check() const;
};

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
  // The global adjustment at the end stops once an iteration lowers its cost by less than this
  // fraction. Local adjustment and loop closure leave it little to do. On the generated five-room
  // suite, the frames' median error against the truth and the adjustment's time:
  //   tolerance   all 6,842 frames (863 keyframes)   the first 2,000 (273)
  //   1e-6        0.69 cm, 17.7 s                     0.57 cm, 2.2 s
  //   1e-4        0.69 cm, 11.6 s                     0.58 cm, 1.3 s
  //   1e-3        0.73 cm,  7.8 s                     0.71 cm, 1.0 s
  // (without the adjustment: 1.8 cm). 1e-3 publishes a streamed suite within 10 s of its end;
  // the price is a millimetre or two on a mid-length run.
  double global_ba_function_tolerance = 1e-3;
  // The end adjustment culls observations its solution does not fit; when they were more than
  // this fraction of its residuals, they may have pulled it, and it runs again without them.
  // Fewer change nothing (the suite: 1 of 443,000, the second run's cost 0.463 px as the first's)
  // and a second run costs as much as the first.
  double global_ba_readjust_fraction = 0.005;
  // A run of more keyframes is adjusted at the end in consecutive pieces of at most this many,
  // each with the keyframes outside it that see its points held. The whole adjustment's linear
  // solve fills in as a long run's places are revisited: on the generated building (3,800
  // keyframes) one iteration took 35 s, 106 s in all. Loop closure has already put the pieces
  // in place; each piece refines its own. A run of at most this many keyframes is adjusted
  // whole, as before.
  int global_ba_max_keyframes = 1000;
  DisparityCalibrationOptions disparity_calibration;
  AssemblyOptions assembly;
  // Threads a build uses (core/util/parallel.h; 0: every core): each frame's features beside its
  // rectification and its keypoints' row searches split among them, and the next frame decoded
  // while one is mapped. The builder sets stereo.threads from it. The same map comes out for any
  // count, to the bit. Bundle adjustment stays on one thread: Ceres's threads sum the Schur
  // complement in the order they finish, so the map would differ in its last bits from run to
  // run (for 15% of KITTI 01's build time).
  int threads = 1;
  void Check() const;  // Checks every nested options struct too.
};

struct MapBuildStats {
  int frames = 0;
  int tracking_failures = 0;
  int keyframes = 0;
  int points = 0;
  int observations = 0;
  int loop_closures = 0;
  int loop_adjustments = 0;  // Closures large enough to correct every keyframe (pose_graph.h).
  double reprojection_rmse_px = 0.0;  // Left image, after global BA.
  double disparity_rmse_px = 0.0;     // Predicted vs measured disparity, after global BA.
  // The rig's, as estimated (DisparityCalibrationOptions) or as given (its `known`).
  DisparityCorrection disparity_correction;
  int calibration_passes = 0;  // Adjustments that estimated it (each but the last remaps).
  VisibilityLearningStats visibility;
  // How the map's up direction was found (MapMetadata::gravity), or why it was not.
  std::string gravity;
  double features_ms = 0, tracking_ms = 0, local_ba_ms = 0, loop_ms = 0, global_ba_ms = 0,
         learning_ms = 0, total_ms = 0;
  int global_ba_pieces = 0;  // The end adjustment's (global_ba_max_keyframes).
  // The frames' keypoints, and of them those searched in the right image: the ones tracking
  // matched to landmarks, and every one of a keyframe (StereoFrameSearch).
  int64_t stereo_keypoints = 0, stereo_searched = 0;
};

// The map a build has so far in the map frame, for drawing while frames arrive: keyframe
// centres and (at most a requested number of) landmark positions, in metres.
struct MapSoFar {
  std::vector<Eigen::Vector3d> keyframe_centres;
  std::vector<Eigen::Vector3d> points;
  int total_points = 0;
};

// Where a build stands after its last frame, for progress reports while frames arrive (mapping
// over the link answers every frame with it).
struct MapBuilderProgress {
  int frames = 0;
  int keyframes = 0;
  int landmarks = 0;         // Not culled.
  int tracked = 0;           // Landmarks the last frame tracked.
  int features = 0;          // The last frame's left corners.
  // The last keyframe's left corners matched in the right image (a frame that is not one
  // searches only the corners it tracked).
  int stereo_matches = 0;
  bool last_tracked = true;  // Whether tracking the last frame succeeded (the first always does).
  int tracking_failures = 0;
  int loop_closures = 0;
  // The last frame's raw left camera in the map frame, as estimated so far (later adjustment
  // moves it).
  Rigid3d map_from_cam;
};

class MapBuilder {
 public:
  // The calibrated pair: raw cameras and the right camera's pose from the left one.
  MapBuilder(const Camera& left, const Camera& right, const Rigid3d& right_from_left,
             const MapBuilderOptions& options);

  // Processes one stereo frame (raw 8-bit grey images of the calibrated size): AddPrepared of
  // its Prepare.
  void AddFrame(int64_t timestamp_ns, const cv::Mat& left_raw, const cv::Mat& right_raw);
  // A frame's features and rectification, for AddPrepared. Reads only the rig and the feature
  // extractor, so one Prepare may run on another thread beside AddPrepared of the frame before
  // (MapStereoFrames): the map is the same.
  StereoFrameSearch Prepare(const cv::Mat& left_raw, const cv::Mat& right_raw) const;
  // Maps a prepared frame: its stereo searches (with the disparity correction as it stands
  // now), tracking, keyframing, local BA and loop closure.
  void AddPrepared(int64_t timestamp_ns, StereoFrameSearch&& frame);
  // Global BA, then the map. Call once, after the last frame.
  Map Finish(const MapMetadata& metadata);

  const MapBuildStats& stats() const { return stats_; }
  // The raw left camera's estimated pose per processed frame, in the map frame.
  Trajectory FrameTrajectory() const;
  // Where the build stands after the last frame added.
  MapBuilderProgress Progress() const;
  // What the build holds in memory, approximately (bytes): every keyframe's features and stereo
  // matches, the landmarks, and the frames kept while the rig's disparity bias is estimated. A
  // server bounds its mapping jobs by it.
  size_t MemoryBytes() const;
  // The map so far, at most `max_points` landmarks (evenly taken).
  MapSoFar MapSoFarView(size_t max_points) const;
  // Short status for progress displays.
  std::string Status() const;

 private:
  // Tracking, keyframing, local BA and loop closure of one frame (its stereo matches searched
  // for the keypoints tracking matches, and all of them if it becomes a keyframe).
  void Process(int64_t timestamp_ns, StereoFrameSearch&& frame);
  // The frame's every keypoint searched (timed with the features), for a keyframe.
  StereoFrame CompleteStereo(StereoFrameSearch&& search);
  // The frame's keypoints into stats_.stereo_keypoints, and those searched (all of a keyframe's)
  // into stats_.stereo_searched.
  void CountSearches(const StereoFrameSearch& frame, bool keyframe);
  void StartKeyframe(int64_t timestamp_ns, StereoFrame&& frame, const Rigid3d& cam_from_world,
                     const std::vector<LandmarkMatch>& tracked);
  // Estimates the disparity correction from the frames so far, mapping them again with it
  // (DisparityCalibrationOptions).
  void CalibrateDisparity();
  // The end's adjustment of every keyframe but the first (global_ba_max_keyframes).
  void GlobalAdjust();
  // How far the camera has travelled, along the keyframes so far (m).
  double TravelledM() const;
  // Forgets every frame processed, to map them again.
  void Restart();
  Rigid3d MapFromWorld() const;
  Rigid3d RectFromRaw() const;
  // What the keyframes and landmarks amount to, counted once per change of them rather than per
  // frame: a server asks for it every frame, and a building's run holds hundreds of thousands of
  // landmarks. Keyframes and landmarks change only when a frame becomes a keyframe (adjustment
  // and loop closure run then), when the build restarts, and at the end.
  struct StateCounts {
    int live_landmarks = 0;  // Not culled.
    size_t bytes = 0;        // Keyframes' features and landmarks (MemoryBytes).
  };
  const StateCounts& Counts() const;

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
  bool last_track_succeeded_ = true;
  int last_features_ = 0;
  int last_stereo_matches_ = 0;
  DisparityCorrection correction_;  // Taken off the disparities of new frames.
  bool calibrating_ = false;
  // The frames so far while calibrating, with their matches as first made (zero correction).
  std::vector<std::pair<int64_t, StereoFrame>> calibration_frames_;
  mutable std::optional<StateCounts> counts_;  // Reset whenever the state changes.
};

}  // namespace visloc::mapping
