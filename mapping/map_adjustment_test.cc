#include "mapping/map_adjustment.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include "core/util/check.h"
#include "core/util/random.h"

namespace visloc::mapping {
namespace {

// Keyframes every 10 cm along a 3 m line, looking ahead (+z) at 2000 points 2-8 m away; each
// keyframe observes the points that project into its image, at their exact (float) pixels.
// MakeSyntheticMap's maps are for storage and scaling and observe points outside the image.
Map TruthMap() {
  Rng rng(11);
  Map map;
  map.metadata.name = "line";
  map.camera = Camera(320, 240, 160.0, 160.0, 159.5, 119.5, Lens(-0.1, 0.01, 1e-4, -2e-4));
  map.features.kind = "harris_surf16";
  map.features.descriptor_type = DescriptorType::kFloat32;
  map.features.descriptor_dim = 16;
  for (int k = 0; k < 30; ++k) {
    map.keyframes.push_back({k * 100'000'000LL, Rigid3d(Eigen::Quaterniond::Identity(),
                                                        Eigen::Vector3d(0.1 * k, 0.0, 0.0))});
  }
  for (int j = 0; j < 2000; ++j) {
    map.points.push_back(
        {Eigen::Vector3d(rng.Uniform(-3, 6), rng.Uniform(-2, 2), rng.Uniform(2, 8)), 0, 0.f});
  }
  map.descriptors = cv::Mat::zeros(2000, 16, CV_32F);
  for (size_t k = 0; k < map.keyframes.size(); ++k) {
    const Rigid3d cam_from_map = map.keyframes[k].map_from_cam.Inverse();
    for (size_t j = 0; j < map.points.size(); ++j) {
      Eigen::Vector2d pixel;
      if (!map.camera.Project(cam_from_map * map.points[j].position_in_map, &pixel) ||
          pixel.x() < 0 || pixel.y() < 0 || pixel.x() > 319 || pixel.y() > 239) {
        continue;
      }
      map.observations.push_back(
          {static_cast<uint32_t>(k), static_cast<uint32_t>(j), pixel.cast<float>()});
    }
  }
  CountObservations(&map);
  std::vector<bool> unseen;
  for (const MapPoint& p : map.points) unseen.push_back(p.observation_count == 0);
  return WithoutPoints(map, unseen);
}

std::vector<bool> FirstHalfFixed(const Map& map) {
  std::vector<bool> fixed(map.keyframes.size(), false);
  for (size_t k = 0; k < map.keyframes.size() / 2; ++k) fixed[k] = true;
  return fixed;
}

// Moves the free keyframes by up to 2 cm and 0.5 degrees, and the points only they see by up to
// 1 cm: what a rigid registration of a second session leaves.
Map Perturbed(const Map& truth, const std::vector<bool>& fixed) {
  Rng rng(3);
  Map map = truth;
  auto noise = [&](double scale) -> Eigen::Vector3d {
    return Eigen::Vector3d(rng.Uniform(-1, 1), rng.Uniform(-1, 1), rng.Uniform(-1, 1)) * scale;
  };
  for (size_t k = 0; k < map.keyframes.size(); ++k) {
    if (fixed[k]) continue;
    const Eigen::Vector3d axis_angle = noise(0.5 * M_PI / 180.0);
    const Rigid3d delta(
        Eigen::Quaterniond(Eigen::AngleAxisd(axis_angle.norm(), axis_angle.normalized())),
        noise(0.02));
    map.keyframes[k].map_from_cam = delta * map.keyframes[k].map_from_cam;
  }
  std::vector<bool> seen_by_fixed(map.points.size(), false);
  for (const Observation& o : map.observations)
    seen_by_fixed[o.point] = seen_by_fixed[o.point] || fixed[o.keyframe];
  for (size_t p = 0; p < map.points.size(); ++p) {
    if (!seen_by_fixed[p]) map.points[p].position_in_map += noise(0.01);
  }
  return map;
}

double MaxKeyframeError(const Map& a, const Map& b) {
  double worst = 0.0;
  for (size_t k = 0; k < a.keyframes.size(); ++k) {
    worst = std::max(
        worst,
        (a.keyframes[k].map_from_cam.translation - b.keyframes[k].map_from_cam.translation).norm());
  }
  return worst;
}

TEST(MapAdjustmentTest, PullsTheFreeKeyframesBackOntoTheFixedOnes) {
  const Map truth = TruthMap();
  const std::vector<bool> fixed = FirstHalfFixed(truth);
  Map map = Perturbed(truth, fixed);
  ASSERT_GT(MaxKeyframeError(map, truth), 0.01);

  const MapAdjustmentStats stats = AdjustMap(&map, fixed, {});

  EXPECT_EQ(stats.fixed_keyframes, 15);
  EXPECT_EQ(stats.free_keyframes, 15);
  EXPECT_GT(stats.initial_rmse_px, 0.5);
  EXPECT_LT(stats.final_rmse_px, 0.01);
  EXPECT_LT(MaxKeyframeError(map, truth), 1e-3);  // 1 mm, from up to 2 cm.
  for (size_t k = 0; k < truth.keyframes.size() / 2; ++k) {
    EXPECT_EQ(map.keyframes[k].map_from_cam.translation,
              truth.keyframes[k].map_from_cam.translation);
  }
  EXPECT_EQ(map.points.size(), truth.points.size());
  EXPECT_TRUE(FindMapProblems(map).empty()) << FindMapProblems(map).front();
}

TEST(MapAdjustmentTest, CullsAnObservationThatFitsNothingAndKeepsTheRest) {
  const Map truth = TruthMap();
  const std::vector<bool> fixed = FirstHalfFixed(truth);
  Map map = Perturbed(truth, fixed);
  // A mismatch in a free keyframe: 40 px off.
  size_t wrong = 0;
  while (fixed[map.observations[wrong].keyframe]) ++wrong;
  map.observations[wrong].pixel.x() += 40.0f;

  const MapAdjustmentStats stats = AdjustMap(&map, fixed, {});

  EXPECT_EQ(stats.culled_observations, 1);
  EXPECT_EQ(map.observations.size(), truth.observations.size() - 1);
  EXPECT_LT(MaxKeyframeError(map, truth), 1e-3);
  EXPECT_TRUE(FindMapProblems(map).empty()) << FindMapProblems(map).front();
}

TEST(MapAdjustmentTest, APointSeenOnceMovesWithItsKeyframe) {
  Map truth = TruthMap();
  const std::vector<bool> fixed = FirstHalfFixed(truth);
  // The last keyframe's first point keeps that keyframe's observation only.
  const uint32_t last = static_cast<uint32_t>(truth.keyframes.size() - 1);
  uint32_t lonely = 0;
  for (const Observation& o : truth.observations) {
    if (o.keyframe == last) {
      lonely = o.point;
      break;
    }
  }
  std::vector<Observation> kept;
  for (const Observation& o : truth.observations) {
    if (o.point != lonely || o.keyframe == last) kept.push_back(o);
  }
  truth.observations = kept;
  CountObservations(&truth);
  Map map = Perturbed(truth, fixed);
  const Eigen::Vector3d in_cam_before =
      map.keyframes[last].map_from_cam.Inverse() * map.points[lonely].position_in_map;

  const MapAdjustmentStats stats = AdjustMap(&map, fixed, {});

  EXPECT_GE(stats.moved_with_keyframe, 1);
  const Eigen::Vector3d in_cam_after =
      map.keyframes[last].map_from_cam.Inverse() * map.points[lonely].position_in_map;
  EXPECT_LT((in_cam_after - in_cam_before).norm(), 1e-9);
}

TEST(MapAdjustmentTest, RefusesToAdjustWithNothingFixed) {
  Map map = TruthMap();
  EXPECT_THROW(AdjustMap(&map, std::vector<bool>(map.keyframes.size(), false), {}), CheckError);
}

}  // namespace
}  // namespace visloc::mapping
