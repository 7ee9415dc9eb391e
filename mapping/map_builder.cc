#include "mapping/map_builder.h"

#include <algorithm>
#include <cmath>
#include <optional>

#include "core/util/check.h"
#include "core/util/parallel.h"
#include "core/util/strings.h"
#include "core/util/timer.h"

namespace visloc::mapping {

void DisparityCalibrationOptions::Check() const {
  VISLOC_CHECK(travel_baselines >= min_travel_baselines && min_travel_baselines > 0 &&
                   max_frames >= 2 && max_passes >= 1 && converged_px > 0,
               "disparity calibration: ", travel_baselines, " and ", min_travel_baselines,
               " baselines, ", max_frames, " frames, ", max_passes, " passes, converged at ",
               converged_px, " px");
  VISLOC_CHECK(offset_sigma_px > 0 && yaw_sigma_deg > 0, "disparity calibration priors ",
               offset_sigma_px, " px, ", yaw_sigma_deg, " deg");
  VISLOC_CHECK(function_tolerance > 0 && function_tolerance < 1,
               "disparity calibration function tolerance ", function_tolerance);
  if (!known) return;
  VISLOC_CHECK(!enabled,
               "a known disparity correction is not estimated again: disable the "
               "calibration to give one");
  VISLOC_CHECK(std::abs(known->offset_px) <= kMaxKnownOffsetPx &&
                   std::abs(known->yaw_deg()) <= kMaxKnownYawDeg,
               "disparity correction ", known->offset_px, " px, ", known->yaw_deg(),
               " deg: at most ", kMaxKnownOffsetPx, " px and ", kMaxKnownYawDeg,
               " deg (calibrate the rig again)");
}

void MapBuilderOptions::Check() const {
  stereo.Check();
  disparity_calibration.Check();
  tracking.Check();
  keyframes.Check();
  loop_closure.Check();
  assembly.Check();
  VISLOC_CHECK(threads >= 0, "map building threads: ", threads, " (0: every core)");
  VISLOC_CHECK(local_ba.max_iterations >= 1 && global_ba_iterations >= 1, "BA iterations ",
               local_ba.max_iterations, ", ", global_ba_iterations);
  VISLOC_CHECK(global_ba_max_keyframes >= 1, "global BA pieces of ", global_ba_max_keyframes,
               " keyframes");
  VISLOC_CHECK(global_ba_function_tolerance > 0 && global_ba_readjust_fraction >= 0,
               "global BA tolerance ", global_ba_function_tolerance, ", readjustment after ",
               global_ba_readjust_fraction);
}

namespace {

Rigid3d RotationOnly(const Eigen::Quaterniond& rotation) {
  return Rigid3d(rotation, Eigen::Vector3d::Zero());
}

RectifiedIntrinsics IntrinsicsOf(const StereoRectifier& rectifier) {
  const Camera& rect = rectifier.rectified_camera();
  return {rect.fx(), rect.cx(), rect.cy(), rectifier.baseline_m()};
}

// The options checked, with `threads` handed to the stages that use it.
MapBuilderOptions Prepared(const MapBuilderOptions& options) {
  options.Check();
  MapBuilderOptions prepared = options;
  prepared.stereo.threads = ResolveThreads(options.threads);
  return prepared;
}

FeatureSettings FeaturesFor(const MapBuilderOptions& options, const Camera& camera) {
  if (!options.scale_feature_count) return options.features;
  return FeatureSettingsForImage(options.features, camera.width(), camera.height());
}

}  // namespace

MapBuilder::MapBuilder(const Camera& left, const Camera& right, const Rigid3d& right_from_left,
                       const MapBuilderOptions& options)
    : left_(left),
      options_(Prepared(options)),
      rectifier_(left, right, right_from_left),
      intrinsics_(IntrinsicsOf(rectifier_)),
      extractor_(CreateFeatureExtractor(FeaturesFor(options, left))),
      tracker_(options.tracking, ViewOf(rectifier_), intrinsics_,
               options.local_ba.disparity_weight),
      loop_closer_(options.loop_closure, tracker_, options.keyframes.window, intrinsics_),
      correction_(options.disparity_calibration.known.value_or(DisparityCorrection{})),
      calibrating_(options.disparity_calibration.enabled) {
  stats_.disparity_correction = correction_;
}

Rigid3d MapBuilder::MapFromWorld() const {
  return RotationOnly(rectifier_.rect_from_left().conjugate());
}

Rigid3d MapBuilder::RectFromRaw() const { return RotationOnly(rectifier_.rect_from_left()); }

void MapBuilder::AddFrame(int64_t timestamp_ns, const cv::Mat& left_raw, const cv::Mat& right_raw) {
  AddPrepared(timestamp_ns, Prepare(left_raw, right_raw));
}

StereoFrameSearch MapBuilder::Prepare(const cv::Mat& left_raw, const cv::Mat& right_raw) const {
  return StereoFrameSearch(left_raw, right_raw, *extractor_, rectifier_, options_.stereo);
}

void MapBuilder::AddPrepared(int64_t timestamp_ns, StereoFrameSearch&& frame) {
  Timer timer;
  frame.SetCorrection(correction_);
  if (calibrating_) {  // Kept whole, to be corrected and mapped again.
    calibration_frames_.emplace_back(timestamp_ns, std::move(frame).Complete());
    frame = StereoFrameSearch(calibration_frames_.back().second);
  }
  stats_.features_ms += frame.prepare_ms() + timer.ElapsedMs();
  ++stats_.frames;
  last_features_ = static_cast<int>(frame.frame().left_rect.size());
  Process(timestamp_ns, std::move(frame));
  const DisparityCalibrationOptions& calibration = options_.disparity_calibration;
  if (calibrating_ && (static_cast<int>(calibration_frames_.size()) >= calibration.max_frames ||
                       TravelledM() >= calibration.travel_baselines * intrinsics_.baseline_m)) {
    CalibrateDisparity();
  }
}

double MapBuilder::TravelledM() const {
  double travelled_m = 0.0;
  for (size_t k = 1; k < state_.keyframes.size(); ++k) {
    travelled_m += (CameraCenter(state_.keyframes[k].cam_from_world) -
                    CameraCenter(state_.keyframes[k - 1].cam_from_world))
                       .norm();
  }
  return travelled_m;
}

namespace {

// The largest shift `change` makes to a disparity anywhere in an image `width` px wide (the
// bias is convex in the column: its extremes are at the edges or the principal point).
double LargestShiftPx(const DisparityCorrection& change, const RectifiedIntrinsics& k, int width) {
  double largest = 0.0;
  for (double x : {0.0, k.cx, width - 1.0}) {
    largest = std::max(largest, std::abs(change.BiasPx(x, k.f, k.cx)));
  }
  return largest;
}

}  // namespace

void MapBuilder::CalibrateDisparity() {
  calibrating_ = false;
  const DisparityCalibrationOptions& calibration = options_.disparity_calibration;
  BundleAdjustmentOptions adjustment = options_.local_ba;
  adjustment.max_iterations = options_.global_ba_iterations;
  adjustment.estimate_disparity_correction = true;
  adjustment.correction_offset_sigma_px = calibration.offset_sigma_px;
  adjustment.correction_yaw_sigma_deg = calibration.yaw_sigma_deg;
  adjustment.function_tolerance = calibration.function_tolerance;
  std::optional<Eigen::Vector2d> previous_change;  // Offset and yaw, both in px.
  const bool observable = TravelledM() >= calibration.min_travel_baselines * intrinsics_.baseline_m;
  for (int pass = 1; observable && pass <= calibration.max_passes; ++pass) {
    Timer timer;
    std::vector<int> free;
    for (int k = 1; k < static_cast<int>(state_.keyframes.size()); ++k) free.push_back(k);
    const DisparityCorrection change =
        BundleAdjust(&state_, free, {0}, intrinsics_, adjustment).correction_change;
    counts_.reset();
    stats_.global_ba_ms += timer.ElapsedMs();
    correction_ = correction_ + change;
    stats_.calibration_passes = pass;
    if (LargestShiftPx(change, intrinsics_, rectifier_.rectified_camera().width()) <
            calibration.converged_px ||
        pass == calibration.max_passes) {
      break;
    }
    // When successive changes shrink by a steady ratio r, the rest of the way is
    // change r / (1 - r) (Aitken's extrapolation). On KITTI 01 an adjustment covers about half of
    // what is left (0.034, then 0.020, 0.011 deg of yaw): extrapolated, three passes land where
    // seven would.
    const Eigen::Vector2d shift(change.offset_px, intrinsics_.f * change.yaw_rad);
    if (previous_change) {
      const double r =
          std::clamp(shift.dot(*previous_change) / previous_change->squaredNorm(), 0.0, 0.8);
      correction_ = correction_ + DisparityCorrection{change.offset_px * r / (1 - r),
                                                      change.yaw_rad * r / (1 - r)};
    }
    previous_change = shift;
    Restart();
    for (const auto& [timestamp_ns, first] : calibration_frames_) {
      StereoFrame frame = first;
      CorrectStereoFrame(correction_, rectifier_, options_.stereo, &frame);
      Process(timestamp_ns, StereoFrameSearch(std::move(frame)));
    }
  }
  stats_.disparity_correction = correction_;
  calibration_frames_.clear();
  calibration_frames_.shrink_to_fit();
}

void MapBuilder::Restart() {
  state_ = SlamState();
  counts_.reset();
  frame_timestamps_ns_.clear();
  frame_from_keyframe_.clear();
  last_cam_from_world_ = Rigid3d::Identity();
  velocity_ = Rigid3d::Identity();
  last_tracked_ = 0;
  last_track_succeeded_ = true;
  loop_closer_.Reset();
  stats_.tracking_failures = stats_.loop_closures = stats_.loop_adjustments = 0;
}

void MapBuilder::Process(int64_t timestamp_ns, StereoFrameSearch&& frame) {
  Timer timer;
  frame_timestamps_ns_.push_back(timestamp_ns);
  if (state_.keyframes.empty()) {
    frame_from_keyframe_.emplace_back(0, Rigid3d::Identity());
    last_cam_from_world_ = Rigid3d::Identity();
    CountSearches(frame, /*keyframe=*/true);
    const double features_before_ms = stats_.features_ms;
    AddKeyframe(&state_, timestamp_ns, CompleteStereo(std::move(frame)), Rigid3d::Identity(), {});
    counts_.reset();
    // Its searches count with the features (CompleteStereo), not twice.
    stats_.tracking_ms += timer.ElapsedMs() - (stats_.features_ms - features_before_ms);
    return;
  }
  const Rigid3d predicted = velocity_ * last_cam_from_world_;
  const TrackResult track =
      tracker_.Track(state_, &frame, predicted, RecentLandmarks(state_, options_.keyframes.window),
                     static_cast<uint64_t>(stats_.frames));
  if (!track.success) ++stats_.tracking_failures;
  last_track_succeeded_ = track.success;
  for (int l : track.in_view) ++state_.landmarks[l].frames_in_view;
  for (const LandmarkMatch& m : track.tracked) ++state_.landmarks[m.landmark].frames_found;
  const Rigid3d& pose = track.cam_from_world;
  last_tracked_ = static_cast<int>(track.tracked.size());
  velocity_ = pose * last_cam_from_world_.Inverse();
  last_cam_from_world_ = pose;
  const SlamKeyframe& keyframe = state_.keyframes.back();
  frame_from_keyframe_.emplace_back(static_cast<int>(state_.keyframes.size()) - 1,
                                    pose * keyframe.cam_from_world.Inverse());
  // The stereo searches tracking asked for count with the features, as a keyframe's do.
  stats_.tracking_ms += timer.ElapsedMs() - frame.search_ms();
  stats_.features_ms += frame.search_ms();
  const bool new_keyframe =
      NeedsKeyframe(options_.keyframes, pose, keyframe.cam_from_world, last_tracked_);
  CountSearches(frame, new_keyframe);
  if (new_keyframe) {
    StartKeyframe(timestamp_ns, CompleteStereo(std::move(frame)), pose, track.tracked);
  }
}

void MapBuilder::CountSearches(const StereoFrameSearch& frame, bool keyframe) {
  const auto keypoints = static_cast<int64_t>(frame.frame().left.size());
  stats_.stereo_keypoints += keypoints;
  stats_.stereo_searched += keyframe ? keypoints : frame.searched();
}

StereoFrame MapBuilder::CompleteStereo(StereoFrameSearch&& search) {
  Timer timer;
  StereoFrame frame = std::move(search).Complete();
  stats_.features_ms += timer.ElapsedMs();
  last_stereo_matches_ = frame.stereo_matches();
  return frame;
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
  counts_.reset();  // New landmarks, and adjustment and closure culled some.
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
    trajectory.push_back(
        {frame_timestamps_ns_[f], map_from_world * cam_from_world.Inverse() * rect_from_raw});
  }
  return trajectory;
}

MapBuilderProgress MapBuilder::Progress() const {
  MapBuilderProgress progress;
  progress.frames = stats_.frames;
  progress.keyframes = static_cast<int>(state_.keyframes.size());
  progress.landmarks = Counts().live_landmarks;
  progress.tracked = last_tracked_;
  progress.features = last_features_;
  progress.stereo_matches = last_stereo_matches_;
  progress.last_tracked = last_track_succeeded_;
  progress.tracking_failures = stats_.tracking_failures;
  progress.loop_closures = stats_.loop_closures;
  progress.map_from_cam = MapFromWorld() * last_cam_from_world_.Inverse() * RectFromRaw();
  return progress;
}

namespace {

// A frame's features: keypoints, descriptors, and one rectified position, grid entry and stereo
// column per keypoint.
size_t FeatureBytes(const FeatureSet& features) {
  const size_t n = features.keypoints.size();
  return n * (sizeof(Keypoint) + sizeof(Eigen::Vector2d) + sizeof(Eigen::Vector2f) +
              2 * sizeof(int) + sizeof(double)) +
         features.descriptors.total() * features.descriptors.elemSize();
}

}  // namespace

const MapBuilder::StateCounts& MapBuilder::Counts() const {
  if (counts_) return *counts_;
  StateCounts counts;
  for (const SlamKeyframe& k : state_.keyframes) counts.bytes += FeatureBytes(k.features);
  for (const Landmark& l : state_.landmarks) {
    counts.bytes += sizeof(Landmark) + l.observations.size() * sizeof(l.observations[0]);
    counts.live_landmarks += !l.culled;
  }
  counts_ = counts;
  return *counts_;
}

size_t MapBuilder::MemoryBytes() const {
  size_t bytes = Counts().bytes;
  for (const auto& [timestamp_ns, frame] : calibration_frames_) {
    bytes += FeatureBytes(frame.left) + frame.point_in_rect.size() * sizeof(Eigen::Vector3d);
  }
  return bytes;
}

MapSoFar MapBuilder::MapSoFarView(size_t max_points) const {
  const Rigid3d map_from_world = MapFromWorld();
  MapSoFar view;
  for (const SlamKeyframe& k : state_.keyframes) {
    view.keyframe_centres.push_back(map_from_world * CameraCenter(k.cam_from_world));
  }
  for (const Landmark& l : state_.landmarks) view.total_points += !l.culled;
  const size_t stride =
      max_points == 0 ? 1 : std::max<size_t>(1, (view.total_points + max_points - 1) / max_points);
  size_t live = 0;
  for (const Landmark& l : state_.landmarks) {
    if (l.culled || live++ % stride != 0) continue;
    view.points.push_back(map_from_world * l.position_in_world);
  }
  return view;
}

std::string MapBuilder::Status() const {
  const MapBuilderProgress progress = Progress();
  return StrCat(progress.keyframes, " keyframes, ", progress.landmarks, " landmarks, ",
                progress.tracked, " tracked, ", progress.loop_closures, " loops");
}

namespace {

// The keyframes outside `piece` (ascending) that observe a landmark a keyframe of it observes.
std::vector<int> HeldAround(const SlamState& state, const std::vector<int>& piece) {
  std::vector<char> in_piece(state.keyframes.size(), 0);
  for (int k : piece) in_piece[k] = 1;
  std::vector<char> held(state.keyframes.size(), 0);
  for (int k : piece) {
    for (int l : state.keyframes[k].landmark) {
      if (l < 0 || state.landmarks[l].culled) continue;
      for (const auto& [kk, i] : state.landmarks[l].observations) held[kk] |= !in_piece[kk];
    }
  }
  std::vector<int> around;
  for (int k = 0; k < static_cast<int>(held.size()); ++k) {
    if (held[k]) around.push_back(k);
  }
  return around;
}

}  // namespace

void MapBuilder::GlobalAdjust() {
  const int n = static_cast<int>(state_.keyframes.size());
  if (n < 2) return;
  BundleAdjustmentOptions global = options_.local_ba;
  global.max_iterations = options_.global_ba_iterations;
  global.function_tolerance = options_.global_ba_function_tolerance;
  // Keyframes 1..n-1 in pieces of equal size; the first keyframe holds the map's frame.
  const int pieces =
      (n - 1 + options_.global_ba_max_keyframes - 1) / options_.global_ba_max_keyframes;
  const int size = (n - 1 + pieces - 1) / pieces;
  for (int begin = 1; begin < n; begin += size) {
    std::vector<int> free;
    for (int k = begin; k < std::min(n, begin + size); ++k) free.push_back(k);
    std::vector<int> held = pieces == 1 ? std::vector<int>{0} : HeldAround(state_, free);
    if (begin == 1) held.push_back(0);  // BundleAdjust takes a keyframe listed twice once.
    const BundleAdjustmentSummary first = BundleAdjust(&state_, free, held, intrinsics_, global);
    if (first.culled_observations >
        options_.global_ba_readjust_fraction * first.residual_blocks) {
      BundleAdjust(&state_, free, held, intrinsics_, global);  // again, without the outliers
    }
    ++stats_.global_ba_pieces;
  }
  counts_.reset();
}

Map MapBuilder::Finish(const MapMetadata& metadata) {
  VISLOC_CHECK(!state_.keyframes.empty(), "no frames were added");
  if (calibrating_) CalibrateDisparity();  // A sequence shorter than the calibration.
  Timer timer;
  const int n = static_cast<int>(state_.keyframes.size());
  GlobalAdjust();
  stats_.global_ba_ms += timer.ElapsedMs();
  timer.Restart();
  AssemblyStats assembly;
  MapMetadata recorded = metadata;
  if (options_.disparity_calibration.known || stats_.calibration_passes > 0) {
    recorded.disparity_correction = correction_;
  }
  recorded.stereo_baseline_m = intrinsics_.baseline_m;
  Map map = AssembleMap(state_, left_, extractor_->settings(), recorded, MapFromWorld(),
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
