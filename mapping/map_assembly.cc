#include "mapping/map_assembly.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/features/descriptor.h"
#include "core/util/check.h"

namespace visloc::mapping {

void AssemblyOptions::Check() const {
  VISLOC_CHECK(min_views >= 1 && cull_min_frames_in_view >= 1 && cull_min_found_ratio >= 0 &&
                   cull_min_found_ratio <= 1,
               "map point thresholds: ", min_views, " views, culled below ", cull_min_found_ratio,
               " of ", cull_min_frames_in_view, " frames");
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

// The views of a landmark: two per keyframe observation with a stereo match, else one.
int CountViews(const SlamState& state, const Landmark& landmark) {
  int views = 0;
  for (const auto& [k, i] : landmark.observations) {
    views += std::isfinite(state.keyframes[k].right_x_rect[i]) ? 2 : 1;
  }
  return views;
}

bool Unconfirmed(const Landmark& landmark, const AssemblyOptions& options) {
  return landmark.observations.size() == 1 &&
         landmark.frames_in_view >= options.cull_min_frames_in_view &&
         landmark.frames_found < options.cull_min_found_ratio * landmark.frames_in_view;
}

// Points from the landmarks kept, with their descriptors; point_of_landmark maps landmark ids
// to point ids (-1 when left out).
void AddPoints(const SlamState& state, const Rigid3d& map_from_world,
               const RectifiedIntrinsics& intrinsics, const AssemblyOptions& options, Map* map,
               std::vector<int>* point_of_landmark, AssemblyStats* stats) {
  point_of_landmark->assign(state.landmarks.size(), -1);
  std::vector<int> descriptor_source;
  double error_sq = 0, disparity_sq = 0;
  int error_count = 0, disparity_count = 0;
  for (size_t l = 0; l < state.landmarks.size(); ++l) {
    const Landmark& landmark = state.landmarks[l];
    if (landmark.culled || CountViews(state, landmark) < options.min_views) continue;
    if (Unconfirmed(landmark, options)) {
      ++stats->culled_unconfirmed;
      continue;
    }
    (*point_of_landmark)[l] = static_cast<int>(map->points.size());
    MapPoint point;
    point.position_in_map = map_from_world * landmark.position_in_world;
    point.observation_count = static_cast<uint32_t>(landmark.observations.size());
    double sum = 0;
    for (const auto& [k, i] : landmark.observations) {
      const ObservationError e = ObservationErrors(state, static_cast<int>(l), k, i, intrinsics);
      sum += e.left_px;
      error_sq += e.left_px * e.left_px;
      ++error_count;
      if (std::isfinite(e.disparity_px)) {
        disparity_sq += e.disparity_px * e.disparity_px;
        ++disparity_count;
      }
    }
    point.mean_reproj_error_px = static_cast<float>(sum / landmark.observations.size());
    map->points.push_back(point);
    descriptor_source.push_back(static_cast<int>(l));
  }
  stats->reprojection_rmse_px = error_count ? std::sqrt(error_sq / error_count) : 0.0;
  stats->disparity_rmse_px = disparity_count ? std::sqrt(disparity_sq / disparity_count) : 0.0;
  const cv::Mat& any = state.keyframes[0].features.descriptors;
  map->descriptors = cv::Mat(static_cast<int>(map->points.size()), any.cols, any.type());
  for (size_t p = 0; p < descriptor_source.size(); ++p) {
    const Landmark& landmark = state.landmarks[descriptor_source[p]];
    const auto& [k, i] = landmark.observations[MedoidObservation(state, landmark)];
    state.keyframes[k].features.descriptors.row(i).copyTo(
        map->descriptors.row(static_cast<int>(p)));
  }
}

}  // namespace

Map AssembleMap(const SlamState& state, const Camera& raw_left_camera,
                const FeatureSettings& features, const MapMetadata& metadata,
                const Rigid3d& map_from_world, const Rigid3d& rect_from_raw,
                const RectifiedIntrinsics& intrinsics, const AssemblyOptions& options,
                AssemblyStats* stats) {
  options.Check();
  VISLOC_CHECK(!state.keyframes.empty(), "no keyframes to assemble");
  Map map;
  map.metadata = metadata;
  map.camera = raw_left_camera;
  map.features = features;
  for (const SlamKeyframe& k : state.keyframes) {
    map.keyframes.push_back(
        {k.timestamp_ns, map_from_world * k.cam_from_world.Inverse() * rect_from_raw});
  }
  std::vector<int> point_of_landmark;
  AddPoints(state, map_from_world, intrinsics, options, &map, &point_of_landmark, stats);
  for (size_t k = 0; k < state.keyframes.size(); ++k) {
    const SlamKeyframe& keyframe = state.keyframes[k];
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
  map.kernel = LearnVisibilityKernel(map, options.visibility, &stats->visibility);
  if (!map.points.empty()) {
    map.appearance.vocabulary = TrainVocabulary(map.descriptors, options.vocabulary);
    std::vector<cv::Mat> keyframe_descriptors;
    for (const SlamKeyframe& k : state.keyframes)
      keyframe_descriptors.push_back(k.features.descriptors);
    IndexKeyframes(keyframe_descriptors, &map.appearance.vocabulary,
                   &map.appearance.keyframe_vectors);
  }
  stats->points = static_cast<int>(map.points.size());
  stats->observations = static_cast<int>(map.observations.size());
  return map;
}

}  // namespace visloc::mapping
