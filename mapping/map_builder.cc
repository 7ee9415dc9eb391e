#include "mapping/map_builder.h"

#include "core/util/check.h"
#include "core/util/strings.h"
#include "core/util/timer.h"

namespace visloc::mapping {

void MapBuilderOptions::Check() const {
  stereo.Check();
  tracking.Check();
  keyframes.Check();
  loop_closure.Check();
  assembly.Check();
  VISLOC_CHECK(local_ba.max_iterations >= 1 && global_ba_iterations >= 1, "BA iterations ",
               local_ba.max_iterations, ", ", global_ba_iterations);
}

namespace {

Rigid3d RotationOnly(const Eigen::Quaterniond& rotation) {
  return Rigid3d(rotation, Eigen::Vector3d::Zero());
}

RectifiedIntrinsics IntrinsicsOf(const StereoRectifier& rectifier) {
  const Camera& rect = rectifier.rectified_camera();
  return {rect.fx(), rect.cx(), rect.cy(), rectifier.baseline_m()};
}

const MapBuilderOptions& Checked(const MapBuilderOptions& options) {
  options.Check();
  return options;
}

FeatureSettings FeaturesFor(const MapBuilderOptions& options, const Camera& camera) {
  if (!options.scale_feature_count) return options.features;
  return FeatureSettingsForImage(options.features, camera.width(), camera.height());
}

}  // namespace

MapBuilder::MapBuilder(const Camera& left, const Camera& right,
                       const Rigid3d& right_from_left, const MapBuilderOptions& options)
    : left_(left),
      options_(Checked(options)),
      rectifier_(left, right, right_from_left),
      intrinsics_(IntrinsicsOf(rectifier_)),
      extractor_(CreateFeatureExtractor(FeaturesFor(options, left))),
      tracker_(options.tracking, ViewOf(rectifier_), intrinsics_,
               options.local_ba.disparity_weight),
      loop_closer_(options.loop_closure, tracker_, options.keyframes.window, intrinsics_,
                   options.local_ba) {}

Rigid3d MapBuilder::MapFromWorld() const {
  return RotationOnly(rectifier_.rect_from_left().conjugate());
}

Rigid3d MapBuilder::RectFromRaw() const { return RotationOnly(rectifier_.rect_from_left()); }

void MapBuilder::AddFrame(int64_t timestamp_ns, const cv::Mat& left_raw, const cv::Mat& right_raw) {
  Timer timer;
  StereoFrame frame =
      BuildStereoFrame(left_raw, right_raw, *extractor_, rectifier_, options_.stereo);
  stats_.features_ms += timer.ElapsedMs();
  ++stats_.frames;
  timer.Restart();
  frame_timestamps_ns_.push_back(timestamp_ns);
  if (state_.keyframes.empty()) {
    frame_from_keyframe_.emplace_back(0, Rigid3d::Identity());
    last_cam_from_world_ = Rigid3d::Identity();
    AddKeyframe(&state_, timestamp_ns, std::move(frame), Rigid3d::Identity(), {});
    stats_.tracking_ms += timer.ElapsedMs();
    return;
  }
  const Rigid3d predicted = velocity_ * last_cam_from_world_;
  const TrackResult track =
      tracker_.Track(state_, frame, predicted, RecentLandmarks(state_, options_.keyframes.window),
                     static_cast<uint64_t>(stats_.frames));
  if (!track.success) ++stats_.tracking_failures;
  for (int l : track.in_view) ++state_.landmarks[l].frames_in_view;
  for (const LandmarkMatch& m : track.tracked) ++state_.landmarks[m.landmark].frames_found;
  const Rigid3d& pose = track.cam_from_world;
  last_tracked_ = static_cast<int>(track.tracked.size());
  velocity_ = pose * last_cam_from_world_.Inverse();
  last_cam_from_world_ = pose;
  const SlamKeyframe& keyframe = state_.keyframes.back();
  frame_from_keyframe_.emplace_back(static_cast<int>(state_.keyframes.size()) - 1,
                                    pose * keyframe.cam_from_world.Inverse());
  stats_.tracking_ms += timer.ElapsedMs();
  if (NeedsKeyframe(options_.keyframes, pose, keyframe.cam_from_world, last_tracked_)) {
    StartKeyframe(timestamp_ns, std::move(frame), pose, track.tracked);
  }
}

void MapBuilder::StartKeyframe(int64_t timestamp_ns, StereoFrame&& frame,
                               const Rigid3d& cam_from_world,
                               const std::vector<LandmarkMatch>& tracked) {
  AddKeyframe(&state_, timestamp_ns, std::move(frame), cam_from_world, tracked);
  Timer timer;
  LocalBundleAdjust(&state_, options_.keyframes, intrinsics_, options_.local_ba);
  stats_.local_ba_ms += timer.ElapsedMs();
  timer.Restart();
  const LoopClosureEvent loop = loop_closer_.TryClose(&state_);
  stats_.loop_closures += loop.closed;
  stats_.loop_adjustments += loop.adjusted;
  stats_.loop_ms += timer.ElapsedMs();
  last_cam_from_world_ = state_.keyframes.back().cam_from_world;
  frame_from_keyframe_.back() = {static_cast<int>(state_.keyframes.size()) - 1,
                                 Rigid3d::Identity()};
}

Trajectory MapBuilder::FrameTrajectory() const {
  const Rigid3d map_from_world = MapFromWorld();
  const Rigid3d rect_from_raw = RectFromRaw();
  Trajectory trajectory;
  for (size_t f = 0; f < frame_from_keyframe_.size(); ++f) {
    const auto& [keyframe, relative] = frame_from_keyframe_[f];
    const Rigid3d cam_from_world = relative * state_.keyframes[keyframe].cam_from_world;
    trajectory.push_back({frame_timestamps_ns_[f],
                          map_from_world * cam_from_world.Inverse() * rect_from_raw});
  }
  return trajectory;
}

std::string MapBuilder::Status() const {
  int landmarks = 0;
  for (const Landmark& l : state_.landmarks) landmarks += !l.culled;
  return StrCat(state_.keyframes.size(), " keyframes, ", landmarks, " landmarks, ", last_tracked_,
                " tracked, ", stats_.loop_closures, " loops");
}

Map MapBuilder::Finish(const MapMetadata& metadata) {
  VISLOC_CHECK(!state_.keyframes.empty(), "no frames were added");
  Timer timer;
  const int n = static_cast<int>(state_.keyframes.size());
  std::vector<int> free;
  for (int k = 1; k < n; ++k) free.push_back(k);
  BundleAdjustmentOptions global = options_.local_ba;
  global.max_iterations = options_.global_ba_iterations;
  if (!free.empty()) {
    BundleAdjust(&state_, free, {0}, intrinsics_, global);
    BundleAdjust(&state_, free, {0}, intrinsics_, global);  // again, after culling outliers
  }
  stats_.global_ba_ms = timer.ElapsedMs();
  timer.Restart();
  AssemblyStats assembly;
  Map map = AssembleMap(state_, left_, extractor_->settings(), metadata, MapFromWorld(),
                        RectFromRaw(), intrinsics_, options_.assembly, &assembly);
  stats_.learning_ms = timer.ElapsedMs();
  stats_.keyframes = n;
  stats_.points = assembly.points;
  stats_.observations = assembly.observations;
  stats_.reprojection_rmse_px = assembly.reprojection_rmse_px;
  stats_.disparity_rmse_px = assembly.disparity_rmse_px;
  stats_.visibility = assembly.visibility;
  return map;
}

}  // namespace visloc::mapping
