#pragma once
// The query side of localization for a robot's whole rig: its cameras (CameraRig), a
// QueryPipeline for each (features, tracker and relocalizer at that camera's radii), and the
// tracker over all of them (RigTracker). Shared, as QueryPipeline is for one camera, by a rig
// session's Localizer and by the Relocalize RPC of several images.

#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

#include <opencv2/core.hpp>

#include "core/localization/query_pipeline.h"
#include "core/localization/rig_tracker.h"
#include "core/util/arrival_predictor.h"
#include "core/util/worker_pool.h"

namespace visloc {

// The cameras a session localizes with, mounted rigidly on the robot. Camera 0 is the
// reference: the session reports its pose, as a one-camera session does. `body_from_cam` places
// each on the body; gyro samples are in the body frame when `body_is_gyro_frame`.
struct CameraRig {
  std::vector<Camera> cameras;
  std::vector<Rigid3d> body_from_cam;
  bool body_is_gyro_frame = false;
  // Camera c's placement on the rig: reference_from_cam^-1 of it (the identity for camera 0).
  Rigid3d CamFromReference(size_t camera) const;
  // Throws InputError unless there are 1 to kMaxCameras cameras, each with its placement.
  void Check() const;
  static constexpr size_t kMaxCameras = 8;
};

class RigPipeline {
 public:
  // Throws InputError for a rig CameraRig::Check refuses.
  RigPipeline(const std::shared_ptr<const LocalizationMap>& map, const CameraRig& rig,
              const LocalizerOptions& options);

  size_t size() const { return cameras_.size(); }
  const QueryPipeline& camera(size_t c) const { return *cameras_[c]; }
  // The tracker over every camera; nullptr for a rig of one camera (its tracker is camera(0)'s).
  const RigTracker* tracker() const { return tracker_.get(); }
  // The threads the cameras are worked on with (LocalizerOptions::rig_threads).
  void SetThreads(int threads);
  // fn(c) for every camera, on up to that many threads (helpers kept from frame to frame).
  void ForEachCamera(const std::function<void(size_t camera)>& fn) const;
  // fn(i) for every i of [0, n) on as many threads, each i claimed in turn by the first thread
  // free for it (WorkerPool::ForEachClaimed): work of unequal parts, balanced.
  void ForEachClaimed(int n, const std::function<void(int i)>& fn) const;
  // The next frame is expected then: the helpers wake for it before it comes
  // (WorkerPool::ExpectJob). Nothing for one camera or one thread.
  void ExpectFrame(const ArrivalPredictor::Expectation& next) const;
  // What the helpers' expectations came to (WorkerPool::expectation_stats).
  WorkerPool::ExpectationStats expectation_stats() const { return workers_->expectation_stats(); }
  // Helpers moved off the caller's core (WorkerPool::helpers_moved).
  int64_t helpers_moved() const { return workers_->helpers_moved(); }

  // Global relocalization of one frame of the rig, with nothing known of where it was taken:
  // each camera's image (`images[c]`; an empty one: that camera gave none) is relocalized as
  // QueryPipeline::RelocalizeImage does, in the rig's order, and the first pose found is moved
  // to the reference camera and verified with every camera's tracking features (RigTracker::
  // Polish). The fix is the reference camera's; the candidates are every camera's, as tried.
  // One camera: RelocalizeImage. Throws InputError for an image that does not fit its camera.
  RelocalizationResult RelocalizeImages(const std::vector<cv::Mat>& images) const;

 private:
  std::vector<std::unique_ptr<QueryPipeline>> cameras_;
  // A helper per camera beside the reference's; its threads start when first used (never for
  // one camera, or one thread).
  std::unique_ptr<WorkerPool> workers_;
  int threads_ = 1;
  std::unique_ptr<RigTracker> tracker_;
};

}  // namespace visloc
