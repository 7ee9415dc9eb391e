#pragma once
// Visibility-guided tracking over a rig of cameras mounted rigidly together (a stereo pair, a
// front and a rear camera, ...): PoseTracker's steps run per camera and one pose solved from
// all of them. From the rig's prior, each camera predicts the points visible from its own pose
// (the learned visibility kernel serves any pose), projects and matches them in its image; PnP
// RANSAC samples within a camera and counts inliers over every camera (SolveRigPnpRansac);
// then each camera re-matches in the tight radius around the rig's RANSAC pose and one
// Levenberg-Marquardt refinement fits the reference camera's pose to all inliers. A camera that
// sees nothing (covered, facing a blank wall) contributes nothing and costs little.
//
// The fix is the reference camera's (camera 0, whose pose a session reports), and so is its
// covariance: the rig's joint (J^T J)^-1, its points' uncertainty through every camera.

#include <functional>
#include <optional>
#include <vector>

#include "core/localization/pose_tracker.h"
#include "core/util/worker_pool.h"

namespace visloc {

class RigTracker {
 public:
  // `trackers[c]` tracks camera c (each built for its own camera, with its radii); they must
  // outlive this. `cam_from_ref[c]` places camera c on the rig (the identity for camera 0). The
  // cameras' predictions and searches run on up to `threads` threads of `workers` (each camera's
  // tracker on one: a PoseTracker is not thread-safe, the map is), which must outlive this; the
  // result is the same for any count.
  RigTracker(std::vector<const PoseTracker*> trackers, std::vector<Rigid3d> cam_from_ref,
             WorkerPool* workers, int threads = 1);

  // One camera's points predicted from the rig's prior and projected into it. It needs no
  // image, so a session runs it beside the cameras' feature extraction (Localizer::ExtractRig).
  struct CameraPrediction {
    std::vector<uint32_t> points;
    PointView map_points;
    std::vector<ProjectedPoint> projected;
    PoseFix fix;  // Its share of PoseFix::predicted and of the predict and project times.
  };
  struct Prediction {
    Rigid3d prior_ref_from_map;
    std::vector<CameraPrediction> cameras;  // Camera c's at c.
  };
  CameraPrediction PredictCamera(size_t camera, const Rigid3d& prior_ref_from_map) const;

  // Full guided estimation from the reference camera's prior. `frames[c]` is camera c's frame;
  // nullptr for a camera without one this time. PoseFix::cameras holds each camera's share.
  // `prediction`, when it was made from this prior, saves predicting again; the fix is the same
  // with it or without.
  PoseFix Track(const std::vector<const QueryFrame*>& frames, const Rigid3d& prior_ref_from_map,
                std::optional<Prediction> prediction = std::nullopt) const;
  // Verification and refinement of a reference pose from elsewhere (a relocalization of one
  // camera, moved to the reference): every camera re-matches in the tight radius around it.
  PoseFix Polish(const std::vector<const QueryFrame*>& frames, const Rigid3d& ref_from_map) const;

  size_t size() const { return trackers_.size(); }
  void set_threads(int threads);
  const Rigid3d& cam_from_ref(size_t camera) const { return cam_from_ref_[camera]; }

 private:
  // One camera's matches and their observations, in the reference camera's pixel units.
  struct CameraMatches {
    std::vector<uint32_t> points;  // Predicted from the prior.
    PointView map_points;
    std::vector<PointMatch> matches;
  };

  // fn(c) for every camera, on up to threads_ threads.
  void ForEachCamera(const std::function<void(size_t)>& fn) const;
  // Each camera's share of the wide search's points (PoseTrackerOptions::coarse_points).
  int CoarsePointsPerCamera(const std::vector<const QueryFrame*>& frames) const;
  // The observations of `camera`'s matches, their pixel scale in the reference camera's focal
  // length (the rig's residuals are weighed in one unit).
  std::vector<PoseObservation> Observations(size_t camera, const QueryFrame& frame,
                                            const CameraMatches& matches) const;
  // Each camera's matches around the rig's pose `ref_from_map` in its tight radius, the joint
  // refinement and the fix's statistics and covariances.
  void RefineAround(const std::vector<const QueryFrame*>& frames,
                    std::vector<CameraMatches>* per_camera, const Rigid3d& ref_from_map,
                    PoseFix* fix) const;
  // Leaves out of `rig` (and `per_camera`) each camera whose inliers under `refined` are not
  // significant against chance (PoseTrackerOptions::rig_camera_min_significance); whether any was.
  bool DropChanceCameras(const RigPnpResult& refined, RigObservations* rig,
                         std::vector<CameraMatches>* per_camera) const;
  void SetCovariances(const std::vector<const QueryFrame*>& frames,
                      const std::vector<CameraMatches>& per_camera, const RigObservations& rig,
                      const RigPnpResult& refined, PoseFix* fix) const;

  std::vector<const PoseTracker*> trackers_;
  std::vector<Rigid3d> cam_from_ref_;
  WorkerPool* workers_ = nullptr;
  int threads_ = 1;
  const PoseTracker& reference() const { return *trackers_.front(); }
};

}  // namespace visloc
