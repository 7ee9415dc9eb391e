#include "mapping/map_builder.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>

#include "core/estimators/pnp_ransac.h"
#include "core/util/check.h"
#include "core/util/strings.h"
#include "core/util/timer.h"

namespace visloc::mapping {

void MapBuilderOptions::Check() const {
  VISLOC_CHECK(search_radius_px > 0 && keyframe_translation_m > 0 && keyframe_rotation_deg > 0,
               "map builder thresholds");
  VISLOC_CHECK(local_window >= 2 && local_free >= 1 && local_free < local_window,
               "local BA window ", local_window, " free ", local_free);
  VISLOC_CHECK(min_point_observations >= 1, "min_point_observations");
  VISLOC_CHECK(loop_adjust_min_correction_m >= 0 && loop_adjust_min_correction_deg >= 0,
               "loop adjustment thresholds ", loop_adjust_min_correction_m, " m ",
               loop_adjust_min_correction_deg, " deg");
}

namespace {

Rigid3d RotationOnly(const Eigen::Quaterniond& rotation) {
  return Rigid3d(rotation, Eigen::Vector3d::Zero());
}

double AngleBetweenDeg(const Rigid3d& a, const Rigid3d& b) {
  return RotationAngleDeg(a.rotation.conjugate() * b.rotation);
}

Eigen::Vector3d Center(const Rigid3d& cam_from_world) {
  return cam_from_world.Inverse().translation;
}

}  // namespace

MapBuilder::MapBuilder(const CameraInfo& left, const CameraInfo& right,
                       const MapBuilderOptions& options)
    : left_(left),
      options_(options),
      rectifier_(left.camera, right.camera, right.body_from_cam.Inverse() * left.body_from_cam),
      extractor_(CreateFeatureExtractor(options.features)) {
  options_.Check();
  const PinholeCamera& rect = rectifier_.rectified_camera();
  intrinsics_ = {rect.fx(), rect.cx(), rect.cy(), rectifier_.baseline_m()};
  options_.search_radius_px *= rect.width() / 320.0;
}

Rigid3d MapBuilder::MapFromWorld() const {
  return RotationOnly(rectifier_.rect_from_left().conjugate());
}

std::vector<int> MapBuilder::RecentLandmarks() const {
  std::set<int> landmarks;
  const int n = static_cast<int>(state_.keyframes.size());
  for (int k = std::max(0, n - options_.local_window); k < n; ++k) {
    for (int l : state_.keyframes[k].landmark) {
      if (l >= 0 && !state_.landmarks[l].culled) landmarks.insert(l);
    }
  }
  return {landmarks.begin(), landmarks.end()};
}

std::vector<MapBuilder::Match> MapBuilder::MatchLandmarks(const StereoFrame& frame,
                                                          const Rigid3d& cam_from_world,
                                                          const std::vector<int>& landmarks,
                                                          double radius_px) const {
  const PinholeCamera& rect = rectifier_.rectified_camera();
  // Bucket the frame's features on a grid of cell size radius for the radius search.
  const int cell = std::max(4, static_cast<int>(radius_px));
  const int cols = rect.width() / cell + 1, rows = rect.height() / cell + 1;
  std::vector<std::vector<int>> grid(cols * rows);
  for (size_t i = 0; i < frame.left_rect.size(); ++i) {
    const int cx = std::clamp(static_cast<int>(frame.left_rect[i].x() / cell), 0, cols - 1);
    const int cy = std::clamp(static_cast<int>(frame.left_rect[i].y() / cell), 0, rows - 1);
    grid[cy * cols + cx].push_back(static_cast<int>(i));
  }
  const bool binary = extractor_->settings().descriptor_type == DescriptorType::kBinary;
  const float max_distance = binary ? 80.0f : 0.6f;
  std::vector<std::pair<int, float>> best_for_feature(frame.left_rect.size(),
                                                      {-1, std::numeric_limits<float>::max()});
  for (int l : landmarks) {
    const Landmark& landmark = state_.landmarks[l];
    const Eigen::Vector3d p = cam_from_world * landmark.position_in_world;
    if (p.z() < 0.1) continue;
    const Eigen::Vector2d projected(intrinsics_.f * p.x() / p.z() + intrinsics_.cx,
                                    intrinsics_.f * p.y() / p.z() + intrinsics_.cy);
    if (!rect.IsInImage(projected)) continue;
    const auto& [ref_k, ref_i] = landmark.observations.back();
    const cv::Mat& ref_descriptors = state_.keyframes[ref_k].features.descriptors;
    NearestTwo nearest;
    const int gx = static_cast<int>(projected.x() / cell),
              gy = static_cast<int>(projected.y() / cell);
    for (int y = std::max(0, gy - 1); y <= std::min(rows - 1, gy + 1); ++y) {
      for (int x = std::max(0, gx - 1); x <= std::min(cols - 1, gx + 1); ++x) {
        for (int i : grid[y * cols + x]) {
          if ((frame.left_rect[i] - projected).squaredNorm() > radius_px * radius_px) continue;
          nearest.Offer(DescriptorDistance(ref_descriptors, ref_i, frame.left.descriptors, i), i);
        }
      }
    }
    if (!nearest.Distinctive(options_.match_ratio, max_distance)) continue;
    const int best_i = nearest.best_index;
    const float best = nearest.best;
    if (best < best_for_feature[best_i].second) best_for_feature[best_i] = {l, best};
  }
  std::vector<Match> matches;
  for (size_t i = 0; i < best_for_feature.size(); ++i) {
    if (best_for_feature[i].first >= 0)
      matches.push_back({best_for_feature[i].first, static_cast<int>(i)});
  }
  return matches;
}

namespace {

std::vector<PoseObservation> ToObservations(const SlamState& state, const StereoFrame& frame,
                                            const std::vector<std::pair<int, int>>& pairs,
                                            const RectifiedIntrinsics& k) {
  std::vector<PoseObservation> observations;
  for (const auto& [l, i] : pairs) {
    PoseObservation o;
    o.point_in_world = state.landmarks[l].position_in_world;
    o.normalized = Eigen::Vector2d((frame.left_rect[i].x() - k.cx) / k.f,
                                   (frame.left_rect[i].y() - k.cy) / k.f);
    if (std::isfinite(frame.right_x_rect[i])) {
      o.has_right = true;
      o.right_x_normalized = (frame.right_x_rect[i] - k.cx) / k.f;
    }
    observations.push_back(o);
  }
  return observations;
}

}  // namespace

void MapBuilder::AddFrame(int64_t timestamp_ns, const cv::Mat& left_raw, const cv::Mat& right_raw) {
  Timer timer;
  StereoFrame frame =
      BuildStereoFrame(left_raw, right_raw, *extractor_, rectifier_, options_.stereo);
  stats_.features_ms += timer.ElapsedMs();
  ++stats_.frames;
  timer.Restart();
  if (state_.keyframes.empty()) {
    frame_cam_from_world_.push_back({timestamp_ns, Rigid3d::Identity()});
    frame_from_keyframe_.emplace_back(0, Rigid3d::Identity());
    AddKeyframe(timestamp_ns, std::move(frame), Rigid3d::Identity(), {});
    stats_.tracking_ms += timer.ElapsedMs();
    return;
  }
  const Rigid3d last = frame_cam_from_world_.back().pose;
  const Rigid3d predicted = velocity_ * last;
  const std::vector<int> landmarks = RecentLandmarks();
  std::vector<Match> matches =
      MatchLandmarks(frame, predicted, landmarks, options_.search_radius_px);
  std::vector<std::pair<int, int>> pairs;
  for (const Match& m : matches) pairs.emplace_back(m.landmark, m.feature);
  PnpRansacOptions pnp;
  pnp.max_error_px = 2.0;
  pnp.min_inliers = 15;
  pnp.seed = static_cast<uint64_t>(stats_.frames);
  pnp.refine.focal_px = intrinsics_.f;
  pnp.refine.baseline_m = intrinsics_.baseline_m;
  pnp.refine.disparity_weight = options_.local_ba.disparity_weight;
  const PnpResult result = SolvePnpRansac(ToObservations(state_, frame, pairs, intrinsics_), pnp);
  Rigid3d pose = predicted;
  std::vector<Match> tracked;
  if (result.success) {
    // Re-match with the estimated pose in a tight radius: more tracks, fewer outliers.
    matches = MatchLandmarks(frame, result.cam_from_world, landmarks, 4.0 * intrinsics_.f / 160.0);
    pairs.clear();
    for (const Match& m : matches) pairs.emplace_back(m.landmark, m.feature);
    const std::vector<PoseObservation> observations =
        ToObservations(state_, frame, pairs, intrinsics_);
    pose = RefinePose(result.cam_from_world, observations, pnp.refine);
    const PoseProjector projector(pose, pnp.refine);
    for (size_t j = 0; j < matches.size(); ++j) {
      if (projector.SquaredErrorPx(observations[j]) <= 4.0) {  // within 2 px
        tracked.push_back(matches[j]);
      }
    }
  } else {
    ++stats_.tracking_failures;
  }
  last_tracked_ = static_cast<int>(tracked.size());
  velocity_ = pose * last.Inverse();
  frame_cam_from_world_.push_back({timestamp_ns, pose});
  frame_from_keyframe_.emplace_back(static_cast<int>(state_.keyframes.size()) - 1,
                                    pose * state_.keyframes.back().cam_from_world.Inverse());
  stats_.tracking_ms += timer.ElapsedMs();

  const Rigid3d& keyframe_pose = state_.keyframes.back().cam_from_world;
  const double moved = (Center(pose) - Center(keyframe_pose)).norm();
  const double turned = AngleBetweenDeg(pose, keyframe_pose);
  if (moved > options_.keyframe_translation_m || turned > options_.keyframe_rotation_deg ||
      last_tracked_ < options_.keyframe_min_tracked) {
    AddKeyframe(timestamp_ns, std::move(frame), pose, tracked);
    timer.Restart();
    LocalBundleAdjust();
    stats_.local_ba_ms += timer.ElapsedMs();
    timer.Restart();
    TryLoopClosure();
    stats_.loop_ms += timer.ElapsedMs();
    frame_cam_from_world_.back().pose = state_.keyframes.back().cam_from_world;
    frame_from_keyframe_.back() = {static_cast<int>(state_.keyframes.size()) - 1,
                                   Rigid3d::Identity()};
  }
}

void MapBuilder::AddKeyframe(int64_t timestamp_ns, StereoFrame&& frame,
                             const Rigid3d& cam_from_world, const std::vector<Match>& tracked) {
  SlamKeyframe keyframe;
  keyframe.timestamp_ns = timestamp_ns;
  keyframe.cam_from_world = cam_from_world;
  keyframe.left_rect = frame.left_rect;
  keyframe.right_x_rect = frame.right_x_rect;
  keyframe.landmark.assign(frame.left.size(), -1);
  const std::vector<Eigen::Vector3d> points = std::move(frame.point_in_rect);
  keyframe.features = std::move(frame.left);
  state_.keyframes.push_back(std::move(keyframe));
  const int k = static_cast<int>(state_.keyframes.size()) - 1;
  for (const Match& m : tracked) state_.Observe(m.landmark, k, m.feature);
  const Rigid3d world_from_cam = cam_from_world.Inverse();
  for (size_t i = 0; i < points.size(); ++i) {
    if (state_.keyframes[k].landmark[i] >= 0 || !points[i].allFinite()) continue;
    Landmark landmark;
    landmark.position_in_world = world_from_cam * points[i];
    state_.landmarks.push_back(landmark);
    state_.Observe(static_cast<int>(state_.landmarks.size()) - 1, k, static_cast<int>(i));
  }
}

void MapBuilder::LocalBundleAdjust() {
  const int n = static_cast<int>(state_.keyframes.size());
  if (n < 2) return;
  std::vector<int> free, fixed;
  for (int k = std::max(0, n - options_.local_window); k < n; ++k) {
    if (k > 0 && k >= n - options_.local_free) {
      free.push_back(k);
    } else {
      fixed.push_back(k);
    }
  }
  BundleAdjust(&state_, free, fixed, intrinsics_, options_.local_ba);
}

void MapBuilder::TryLoopClosure() {
  if (!options_.loop_closure || ++keyframes_since_loop_ <= options_.loop_cooldown_keyframes) return;
  const int k = static_cast<int>(state_.keyframes.size()) - 1;
  const SlamKeyframe& current = state_.keyframes[k];
  const Eigen::Vector3d center = Center(current.cam_from_world);
  std::vector<std::pair<double, int>> candidates;
  for (int j = 0; j < k - options_.loop_min_keyframe_gap; ++j) {
    const double distance = (Center(state_.keyframes[j].cam_from_world) - center).norm();
    if (distance < options_.loop_radius_m &&
        AngleBetweenDeg(state_.keyframes[j].cam_from_world, current.cam_from_world) <
            options_.loop_max_angle_deg) {
      candidates.emplace_back(distance, j);
    }
  }
  std::sort(candidates.begin(), candidates.end());
  // A view of the current keyframe as a frame, to reuse the projection matcher.
  StereoFrame view;
  view.left = current.features;
  view.left_rect = current.left_rect;
  view.right_x_rect = current.right_x_rect;
  for (size_t c = 0; c < std::min<size_t>(3, candidates.size()); ++c) {
    const int j = candidates[c].second;
    std::vector<int> old_landmarks;
    for (int l : state_.keyframes[j].landmark) {
      if (l < 0 || state_.landmarks[l].culled) continue;
      bool seen_now = false;
      for (const auto& [kk, ii] : state_.landmarks[l].observations)
        seen_now |= (kk >= k - options_.local_window);
      if (!seen_now) old_landmarks.push_back(l);
    }
    const std::vector<Match> matches = MatchLandmarks(view, current.cam_from_world, old_landmarks,
                                                      1.5 * options_.search_radius_px);
    if (static_cast<int>(matches.size()) < options_.loop_min_inliers) continue;
    std::vector<std::pair<int, int>> pairs;
    for (const Match& m : matches) pairs.emplace_back(m.landmark, m.feature);
    PnpRansacOptions pnp;
    pnp.min_inliers = options_.loop_min_inliers;
    pnp.refine.focal_px = intrinsics_.f;
    pnp.refine.baseline_m = intrinsics_.baseline_m;
    pnp.refine.disparity_weight = options_.local_ba.disparity_weight;
    const PnpResult result = SolvePnpRansac(ToObservations(state_, view, pairs, intrinsics_), pnp);
    if (!result.success) continue;
    // Geometrically verified: the current keypoints are the old landmarks. Merge tracks.
    for (size_t m = 0; m < matches.size(); ++m) {
      if (!result.inlier_mask[m]) continue;
      const int old_l = matches[m].landmark, i = matches[m].feature;
      const int current_l = state_.keyframes[k].landmark[i];
      if (current_l == old_l) continue;
      if (current_l >= 0) {
        Landmark& merged = state_.landmarks[current_l];
        for (const auto& [kk, ii] : merged.observations) {
          bool old_has_keyframe = false;
          for (const auto& [ok, oi] : state_.landmarks[old_l].observations)
            old_has_keyframe |= ok == kk;
          state_.keyframes[kk].landmark[ii] = -1;
          if (!old_has_keyframe) state_.Observe(old_l, kk, ii);
        }
        merged.observations.clear();
        merged.culled = true;
      } else {
        state_.Observe(old_l, k, i);
      }
    }
    ++stats_.loop_closures;
    keyframes_since_loop_ = 0;
    // A large correction is spread over the whole trajectory now, while it is small enough for
    // bundle adjustment to converge; the local window alone would bend the path at the closure.
    // A small one (most closures: revisits of mapped places) is left to local bundle adjustment
    // and to the global one at the end. Re-adjusting every keyframe at every closure made
    // mapping quadratic in its length without making the map more accurate.
    const double correction_m = (Center(result.cam_from_world) - center).norm();
    const double correction_deg = AngleBetweenDeg(result.cam_from_world, current.cam_from_world);
    if (correction_m < options_.loop_adjust_min_correction_m &&
        correction_deg < options_.loop_adjust_min_correction_deg) {
      return;
    }
    ++stats_.loop_adjustments;
    std::vector<int> all_free;
    for (int kk = 1; kk <= k; ++kk) all_free.push_back(kk);
    BundleAdjustmentOptions global = options_.local_ba;
    global.max_iterations = 10;
    BundleAdjust(&state_, all_free, {0}, intrinsics_, global);
    return;
  }
}

Trajectory MapBuilder::FrameTrajectory() const {
  const Rigid3d map_from_world = MapFromWorld();
  const Rigid3d rect_from_raw = RotationOnly(rectifier_.rect_from_left());
  Trajectory trajectory;
  for (size_t f = 0; f < frame_cam_from_world_.size(); ++f) {
    const auto& [keyframe, relative] = frame_from_keyframe_[f];
    const Rigid3d cam_from_world = relative * state_.keyframes[keyframe].cam_from_world;
    trajectory.push_back({frame_cam_from_world_[f].timestamp_ns,
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

namespace {

// The observation descriptor with the smallest summed distance to the others (the medoid).
int MedoidObservation(const SlamState& state, const Landmark& landmark) {
  int best = 0;
  float best_sum = std::numeric_limits<float>::max();
  for (size_t a = 0; a < landmark.observations.size(); ++a) {
    float sum = 0;
    const auto& [ka, ia] = landmark.observations[a];
    for (size_t b = 0; b < landmark.observations.size(); ++b) {
      const auto& [kb, ib] = landmark.observations[b];
      sum += DescriptorDistance(state.keyframes[ka].features.descriptors, ia,
                                state.keyframes[kb].features.descriptors, ib);
    }
    if (sum < best_sum) {
      best_sum = sum;
      best = static_cast<int>(a);
    }
  }
  return best;
}

}  // namespace

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

  Map map;
  map.metadata = metadata;
  map.camera = left_.camera;
  map.features = extractor_->settings();
  const Rigid3d map_from_world = MapFromWorld();
  const Rigid3d rect_from_raw = RotationOnly(rectifier_.rect_from_left());
  for (const SlamKeyframe& k : state_.keyframes) {
    map.keyframes.push_back(
        {k.timestamp_ns, map_from_world * k.cam_from_world.Inverse() * rect_from_raw});
  }
  std::vector<int> point_of_landmark(state_.landmarks.size(), -1);
  std::vector<int> descriptor_source;
  double error_sq = 0, disparity_sq = 0;
  int error_count = 0, disparity_count = 0;
  for (size_t l = 0; l < state_.landmarks.size(); ++l) {
    const Landmark& landmark = state_.landmarks[l];
    if (landmark.culled ||
        static_cast<int>(landmark.observations.size()) < options_.min_point_observations)
      continue;
    point_of_landmark[l] = static_cast<int>(map.points.size());
    MapPoint point;
    point.position_in_map = map_from_world * landmark.position_in_world;
    point.observation_count = static_cast<uint32_t>(landmark.observations.size());
    double sum = 0;
    for (const auto& [k, i] : landmark.observations) {
      const ObservationError e = ObservationErrors(state_, static_cast<int>(l), k, i, intrinsics_);
      sum += e.left_px;
      error_sq += e.left_px * e.left_px;
      ++error_count;
      if (std::isfinite(e.disparity_px)) {
        disparity_sq += e.disparity_px * e.disparity_px;
        ++disparity_count;
      }
    }
    point.mean_reproj_error_px = static_cast<float>(sum / landmark.observations.size());
    map.points.push_back(point);
    descriptor_source.push_back(static_cast<int>(l));
  }
  stats_.reprojection_rmse_px = error_count ? std::sqrt(error_sq / error_count) : 0.0;
  stats_.disparity_rmse_px = disparity_count ? std::sqrt(disparity_sq / disparity_count) : 0.0;
  const cv::Mat& any = state_.keyframes[0].features.descriptors;
  map.descriptors = cv::Mat(static_cast<int>(map.points.size()), any.cols, any.type());
  for (size_t p = 0; p < descriptor_source.size(); ++p) {
    const Landmark& landmark = state_.landmarks[descriptor_source[p]];
    const auto& [k, i] = landmark.observations[MedoidObservation(state_, landmark)];
    state_.keyframes[k].features.descriptors.row(i).copyTo(
        map.descriptors.row(static_cast<int>(p)));
  }
  for (int k = 0; k < n; ++k) {
    const SlamKeyframe& keyframe = state_.keyframes[k];
    std::vector<Observation> observations;
    for (size_t i = 0; i < keyframe.landmark.size(); ++i) {
      const int l = keyframe.landmark[i];
      if (l < 0 || point_of_landmark[l] < 0) continue;
      observations.push_back({static_cast<uint32_t>(k), static_cast<uint32_t>(point_of_landmark[l]),
                              keyframe.features.keypoints[i].pixel});
    }
    std::sort(observations.begin(), observations.end(),
              [](const Observation& a, const Observation& b) { return a.point < b.point; });
    map.observations.insert(map.observations.end(), observations.begin(), observations.end());
  }
  map.kernel = LearnVisibilityKernel(map, options_.visibility, &stats_.visibility);
  if (!map.points.empty()) {
    map.appearance.vocabulary = TrainVocabulary(map.descriptors, options_.vocabulary);
    std::vector<cv::Mat> keyframe_descriptors;
    for (const SlamKeyframe& k : state_.keyframes)
      keyframe_descriptors.push_back(k.features.descriptors);
    IndexKeyframes(keyframe_descriptors, &map.appearance.vocabulary,
                   &map.appearance.keyframe_vectors);
  }
  stats_.learning_ms = timer.ElapsedMs();
  stats_.keyframes = n;
  stats_.points = static_cast<int>(map.points.size());
  stats_.observations = static_cast<int>(map.observations.size());
  return map;
}

Map BuildMap(const Dataset& dataset, const MapBuilderOptions& options, const MapMetadata& metadata,
             MapBuildStats* stats, Trajectory* frame_trajectory,
             const std::function<void(int, int, const std::string&)>& progress) {
  if (!dataset.has_stereo())
    throw InputError(StrCat(dataset.root, ": map building needs a stereo dataset (no cam1)"));
  Timer timer;
  MapBuilder builder(dataset.left, *dataset.right, options);
  const int total = static_cast<int>(dataset.frames.size());
  for (int i = 0; i < total; ++i) {
    const FrameRecord& frame = dataset.frames[i];
    const cv::Mat left =
        LoadGreyImage(frame.left_path, dataset.left.camera.width(), dataset.left.camera.height());
    const cv::Mat right = LoadGreyImage(frame.right_path, dataset.right->camera.width(),
                                        dataset.right->camera.height());
    builder.AddFrame(frame.timestamp_ns, left, right);
    if (progress) progress(i + 1, total, builder.Status());
  }
  if (progress) progress(total, total, "global bundle adjustment, visibility learning, vocabulary");
  Map map = builder.Finish(metadata);
  if (stats) {
    *stats = builder.stats();
    stats->total_ms = timer.ElapsedMs();
  }
  if (frame_trajectory) *frame_trajectory = builder.FrameTrajectory();
  return map;
}

}  // namespace visloc::mapping
