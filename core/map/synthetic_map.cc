#include "core/map/synthetic_map.h"

#include <algorithm>
#include <cmath>

#include "core/map/vocabulary.h"
#include "core/util/check.h"
#include "core/util/random.h"

namespace visloc {

namespace {

// Deterministic in `rng` (cv::randu would draw from OpenCV's global generator).
cv::Mat RandomDescriptors(int rows, const SyntheticMapOptions& options, Rng& rng) {
  if (options.descriptor_type == DescriptorType::kFloat32) {
    cv::Mat descriptors(rows, options.descriptor_dim, CV_32F);
    for (int j = 0; j < rows; ++j) {
      for (int d = 0; d < options.descriptor_dim; ++d) {
        descriptors.at<float>(j, d) = static_cast<float>(rng.Uniform(-1, 1));
      }
    }
    return descriptors;
  }
  cv::Mat descriptors(rows, options.descriptor_dim, CV_8U);
  for (int j = 0; j < rows; ++j) {
    for (int d = 0; d < options.descriptor_dim; ++d) {
      descriptors.at<uint8_t>(j, d) = static_cast<uint8_t>(rng.NextU64());
    }
  }
  return descriptors;
}

}  // namespace

Map MakeSyntheticMap(const SyntheticMapOptions& options) {
  VISLOC_CHECK(options.keyframes >= 1 && options.points >= 0 && options.observations_per_point >= 1,
               "synthetic map of ", options.keyframes, " keyframes, ", options.points, " points");
  VISLOC_CHECK(options.observations_per_point <= options.keyframes,
               "more observations per point than keyframes");
  Rng rng(options.seed);
  Map map;
  map.metadata = {options.name, 1'700'000'000, "synthetic", "visloc synthetic map", ""};
  map.camera = Camera(320, 240, 160.0, 160.0, 159.5, 119.5, {-0.1, 0.01, 1e-4, -2e-4});
  map.features.kind = options.descriptor_type == DescriptorType::kFloat32 ? "harris_surf16" : "orb";
  map.features.descriptor_type = options.descriptor_type;
  map.features.descriptor_dim = options.descriptor_dim;
  // Parameters every extractor kind accepts, so sessions can run on synthetic maps.
  map.features.params = {{"max_features", 500}, {"grid_cols", 8}};

  // Keyframes ~0.15 m apart: on a loop, looking outwards, as a robot walking a circle; or along
  // lanes, looking where they walk.
  const double radius = std::max(0.5, options.keyframes * 0.15 / (2 * M_PI));
  const int per_lane = std::max(1, static_cast<int>(options.lane_length_m / 0.15));
  for (int k = 0; k < options.keyframes; ++k) {
    Eigen::Vector3d forward, center;
    if (options.lane_length_m > 0) {
      const int lane = k / per_lane;
      const double along = 0.15 * (k % per_lane);
      const bool back = lane % 2 == 1;
      forward = Eigen::Vector3d(back ? -1 : 1, 0, 0);
      center = Eigen::Vector3d(back ? options.lane_length_m - along : along, 3.0 * lane, 0);
    } else {
      const double angle = 2 * M_PI * k / options.keyframes;
      forward = Eigen::Vector3d(std::cos(angle), std::sin(angle), 0);
      center = radius * forward;
    }
    // Camera z (forward), camera y down (world -z), x completes it.
    const Eigen::Vector3d down(0, 0, -1);
    Eigen::Matrix3d map_from_cam_rotation;
    map_from_cam_rotation.col(0) = down.cross(forward);
    map_from_cam_rotation.col(1) = down;
    map_from_cam_rotation.col(2) = forward;
    map.keyframes.push_back(
        {1'700'000'000'000'000'000 + k * 500'000'000LL, Rigid3d(map_from_cam_rotation, center)});
  }
  // Each point sits 1-6 m in front of its first keyframe; the next keyframes see it too.
  std::vector<std::vector<uint32_t>> seen_by(options.keyframes);
  map.points.resize(options.points);
  for (int j = 0; j < options.points; ++j) {
    const int first = rng.UniformInt(0, options.keyframes - 1);
    const Rigid3d& pose = map.keyframes[first].map_from_cam;
    const Eigen::Vector3d in_cam(rng.Uniform(-1.5, 1.5), rng.Uniform(-1.0, 1.0), 1.0);
    map.points[j].position_in_map = pose * (in_cam * rng.Uniform(1.0, 6.0));
    map.points[j].observation_count = options.observations_per_point;
    map.points[j].mean_reproj_error_px = static_cast<float>(rng.Uniform(0.1, 1.0));
    for (int o = 0; o < options.observations_per_point; ++o) {
      seen_by[(first + o) % options.keyframes].push_back(static_cast<uint32_t>(j));
    }
  }
  for (int k = 0; k < options.keyframes; ++k) {
    std::sort(seen_by[k].begin(), seen_by[k].end());
    const Rigid3d cam_from_map = map.keyframes[k].map_from_cam.Inverse();
    for (uint32_t j : seen_by[k]) {
      Eigen::Vector2d pixel(-1, -1);
      map.camera.Project(cam_from_map * map.points[j].position_in_map, &pixel);
      map.observations.push_back({static_cast<uint32_t>(k), j, pixel.cast<float>()});
    }
  }
  map.descriptors = RandomDescriptors(options.points, options, rng);
  map.kernel.cues = {"translation_m", "view_direction"};
  map.kernel.metric = Eigen::Matrix2d{{2.0, 0.1}, {0.1, 3.0}};
  if (options.appearance) {
    VISLOC_CHECK(options.vocabulary_depth >= 1 && options.vocabulary_depth <= 5,
                 "vocabulary depth ", options.vocabulary_depth);
    Vocabulary& vocabulary = map.appearance.vocabulary;
    vocabulary.branching = 8;
    vocabulary.depth = options.vocabulary_depth;
    int nodes = 0, words = 1;
    for (int level = 1; level <= vocabulary.depth; ++level) {
      words *= 8;
      nodes += words;
    }
    vocabulary.centroids = RandomDescriptors(nodes, options, rng);
    for (int w = 0; w < words; ++w)
      vocabulary.word_weights.push_back(static_cast<float>(rng.Uniform(0.1, 3)));
    for (int k = 0; k < options.keyframes; ++k) {
      BowVector vector;
      if (options.appearance_from_descriptors) {
        cv::Mat seen;
        for (uint32_t j : seen_by[k]) seen.push_back(map.descriptors.row(static_cast<int>(j)));
        vector = ComputeBow(vocabulary, seen);
      } else {
        for (uint32_t w = 0; w < static_cast<uint32_t>(words); ++w) {
          if (rng.Uniform01() < 0.3) vector.emplace_back(w, static_cast<float>(rng.Uniform01()));
        }
        // L1-normalized, as ComputeBow makes them.
        float total = 0.0f;
        for (const auto& entry : vector) total += entry.second;
        for (auto& entry : vector) entry.second /= total;
      }
      map.appearance.keyframe_vectors.push_back(std::move(vector));
    }
  }
  return map;
}

}  // namespace visloc
