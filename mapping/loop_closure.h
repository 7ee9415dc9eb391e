#pragma once
// Loop closure (seed paper 000, sec. 3.3): after each keyframe, old keyframes near its pose and
// of similar orientation, not among the recent ones, are candidates. Their landmarks that the
// recent keyframes no longer see are matched to the new keyframe's keypoints by projection and
// verified by PnP RANSAC; the verified matches merge the old tracks with the new ones. A
// closure whose pose correction is large corrects every keyframe through the pose graph
// (pose_graph.h).

#include <vector>

#include "core/camera/camera.h"
#include "mapping/frame_tracker.h"
#include "mapping/pose_graph.h"
#include "mapping/slam_state.h"

namespace visloc::mapping {

struct LoopClosureOptions {
  bool enabled = true;
  double radius_m = 0.7;        // Candidate keyframes' centres within this of the new one.
  double max_angle_deg = 35.0;  // and their orientations within this.
  int min_keyframe_gap = 15;    // Candidates are at least this many keyframes older.
  int max_candidates = 3;       // Nearest first.
  int min_inliers = 25;         // Matches before RANSAC, and RANSAC inliers.
  int cooldown_keyframes = 5;   // After a closure, the next few keyframes see the same loop.
  // Projection search radius at 320 pixels of width: the drift a loop accumulated is larger
  // than a frame's motion (1.5 x the tracking radius).
  double search_radius_px = 22.5;
  // A closure whose pose correction (the keyframe's pose from the old landmarks against its
  // tracked pose) reaches either bound corrects every keyframe through the pose graph.
  double adjust_min_correction_m = 0.05;
  double adjust_min_correction_deg = 1.0;
  PoseGraphOptions pose_graph;
  void Check() const;
};

struct LoopClosureEvent {
  bool closed = false;
  bool adjusted = false;  // Every keyframe was corrected through the pose graph.
};

class LoopCloser {
 public:
  // `window` is tracking's keyframe window: landmarks seen in it are current, not a loop.
  LoopCloser(const LoopClosureOptions& options, const FrameTracker& tracker, int window,
             const RectifiedIntrinsics& intrinsics);

  // Tries to close a loop at the state's last keyframe.
  LoopClosureEvent TryClose(SlamState* state);
  // Forgets past closures, for a state mapped again from its first frame.
  void Reset() { keyframes_since_loop_ = 1000; }

 private:
  // The landmarks of keyframe `j` that no keyframe of the window before `k` observes.
  std::vector<int> OldLandmarks(const SlamState& state, int j, int k) const;
  // Merges the verified matches' current tracks into the old landmarks.
  static void MergeTracks(SlamState* state, int k, const std::vector<LandmarkMatch>& matches,
                          const std::vector<char>& inliers);

  LoopClosureOptions options_;  // search_radius_px scaled to the image width.
  const FrameTracker& tracker_;
  int window_;
  RectifiedIntrinsics intrinsics_;
  int keyframes_since_loop_ = 1000;
};

}  // namespace visloc::mapping
