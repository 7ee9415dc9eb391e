#include "core/localization/rig_pipeline.h"

#include <optional>

#include "core/util/check.h"
#include "core/util/timer.h"

namespace visloc {

Rigid3d CameraRig::CamFromReference(size_t camera) const {
  if (camera == 0) return Rigid3d();  // Exactly, not to rounding.
  return body_from_cam[camera].Inverse() * body_from_cam[0];
}

void CameraRig::Check() const {
  if (cameras.empty() || cameras.size() > kMaxCameras) {
    throw InputError(StrCat("a rig has 1 to ", kMaxCameras, " cameras, not ", cameras.size()));
  }
  if (body_from_cam.size() != cameras.size()) {
    throw InputError(StrCat("a rig of ", cameras.size(), " cameras needs as many placements, not ",
                            body_from_cam.size()));
  }
}

RigPipeline::RigPipeline(const std::shared_ptr<const LocalizationMap>& map, const CameraRig& rig,
                         const LocalizerOptions& options)
    : workers_(std::make_unique<WorkerPool>(static_cast<int>(rig.cameras.size()) - 1)),
      threads_(options.rig_threads) {
  rig.Check();
  std::vector<const PoseTracker*> trackers;
  std::vector<Rigid3d> cam_from_ref;
  for (size_t c = 0; c < rig.cameras.size(); ++c) {
    cameras_.push_back(std::make_unique<QueryPipeline>(map, rig.cameras[c], options));
    trackers.push_back(&cameras_.back()->tracker());
    cam_from_ref.push_back(rig.CamFromReference(c));
  }
  if (cameras_.size() > 1) {
    tracker_ = std::make_unique<RigTracker>(std::move(trackers), std::move(cam_from_ref),
                                            workers_.get(), threads_);
  }
}

void RigPipeline::SetThreads(int threads) {
  threads_ = threads;
  if (tracker_) tracker_->set_threads(threads);
}

void RigPipeline::ForEachCamera(const std::function<void(size_t camera)>& fn) const {
  workers_->ForEach(static_cast<int>(cameras_.size()), threads_,
                    [&](int c) { fn(static_cast<size_t>(c)); });
}

void RigPipeline::ForEachClaimed(int n, const std::function<void(int i)>& fn) const {
  workers_->ForEachClaimed(n, threads_, fn);
}

void RigPipeline::ExpectFrame(const ArrivalPredictor::Expectation& next) const {
  if (cameras_.size() > 1 && threads_ > 1) workers_->ExpectJob(next.when, next.lead, next.grace);
}

RelocalizationResult RigPipeline::RelocalizeImages(const std::vector<cv::Mat>& images) const {
  VISLOC_CHECK(images.size() == cameras_.size(), "a rig of ", cameras_.size(), " cameras given ",
               images.size(), " images");
  if (!tracker_) return cameras_[0]->RelocalizeImage(images[0]);
  const Timer timer;
  RelocalizationResult joint;
  joint.feature_passes = 0;
  // Every camera's tracking features, for the verification: those a camera's relocalization
  // extracted in its first pass, the others extracted once (side by side), when a camera has
  // found a pose to verify.
  std::vector<std::optional<QueryFrame>> frames(cameras_.size());
  std::vector<const QueryFrame*> frame_pointers;
  const auto verified = [&](const Rigid3d& ref_from_map) {
    if (frame_pointers.empty()) {
      const Timer features;
      ForEachCamera([&](size_t c) {
        if (!frames[c] && !images[c].empty()) frames[c].emplace(cameras_[c]->Extract(images[c]));
      });
      for (const std::optional<QueryFrame>& frame : frames) {
        frame_pointers.push_back(frame ? &*frame : nullptr);
      }
      joint.times.features_ms += features.ElapsedMs();
    }
    const Timer verification;
    PoseFix fix = tracker_->Polish(frame_pointers, ref_from_map);
    joint.times.verification_ms += verification.ElapsedMs();
    return fix;
  };
  for (size_t c = 0; c < cameras_.size() && !joint.success; ++c) {
    if (images[c].empty()) continue;
    std::optional<QueryFrame> tracking_frame;
    RelocalizationResult found =
        cameras_[c]->RelocalizeImage(images[c], frame_pointers.empty() ? &tracking_frame : nullptr);
    if (tracking_frame) frames[c] = std::move(tracking_frame);
    joint.candidates.insert(joint.candidates.end(), found.candidates.begin(),
                            found.candidates.end());
    joint.times += found.times;
    joint.feature_passes = std::max(joint.feature_passes, found.feature_passes);
    if (!found.success) continue;
    // Camera c's pose moved to the reference: ref_from_map = cam_from_ref^-1 cam_from_map.
    PoseFix fix = verified(tracker_->cam_from_ref(c).Inverse() * found.fix.cam_from_map);
    if (!fix.success) continue;
    joint.success = true;
    joint.fix = std::move(fix);
    joint.keyframe = found.keyframe;
  }
  joint.ms = timer.ElapsedMs();
  return joint;
}

}  // namespace visloc
