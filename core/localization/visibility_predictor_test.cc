#include "core/localization/visibility_predictor.h"

#include <gtest/gtest.h>

#include <set>

#include "core/map/synthetic_map.h"
#include "core/util/check.h"

namespace visloc {
namespace {

Map TestMap() {
  SyntheticMapOptions options;
  options.keyframes = 40;
  options.points = 4000;
  options.observations_per_point = 4;
  return MakeSyntheticMap(options);
}

TEST(VisibilityPredictorTest, AtAKeyframePoseThePredictionIsWhatItSaw) {
  const LocalizationMap map(TestMap());
  VisibilityOptions options;
  options.k = 1;
  options.probability_threshold = 0.5;
  const VisibilityPredictor predictor(map, options);
  const int keyframe = 17;
  const auto predicted = predictor.Predict(map.map().keyframes[keyframe].map_from_cam);
  std::set<uint32_t> predicted_points;
  for (const PredictedPoint& p : predicted) predicted_points.insert(p.point);
  const auto seen = map.VisiblePoints(keyframe);
  EXPECT_EQ(predicted_points, std::set<uint32_t>(seen.begin(), seen.end()));
  EXPECT_EQ(predictor.NearestKeyframes(map.map().keyframes[keyframe].map_from_cam).front().first,
            keyframe);
}

TEST(VisibilityPredictorTest, ProbabilitiesVoteOverNeighboursAndThresholdPrunes) {
  const LocalizationMap map(TestMap());
  const Rigid3d pose = map.map().keyframes[10].map_from_cam;
  VisibilityOptions all;
  all.probability_threshold = 0.0;
  VisibilityOptions pruned;  // paper: K = 10, P_t = 0.2
  VisibilityStats all_stats, pruned_stats;
  const auto everything = VisibilityPredictor(map, all).Predict(pose, &all_stats);
  const auto likely = VisibilityPredictor(map, pruned).Predict(pose, &pruned_stats);
  EXPECT_EQ(all_stats.keyframes_used, 10);
  EXPECT_EQ(all_stats.predicted, all_stats.candidates);
  EXPECT_LT(pruned_stats.predicted, all_stats.predicted);
  for (const PredictedPoint& p : likely) {
    EXPECT_GT(p.probability, 0.2f);
    EXPECT_LE(p.probability, 1.0f + 1e-6f);
  }
  ASSERT_FALSE(likely.empty());
  EXPECT_GE(likely.front().probability, likely.back().probability);
  // Every point the keyframe at the pose saw is predicted: the nearest keyframe dominates.
  std::set<uint32_t> likely_points;
  for (const PredictedPoint& p : likely) likely_points.insert(p.point);
  for (uint32_t point : map.VisiblePoints(10)) EXPECT_TRUE(likely_points.count(point)) << point;
}

TEST(VisibilityPredictorTest, TransparentWorldIsEveryPointInViewAndNothingElse) {
  const LocalizationMap map(TestMap());
  const Camera& camera = map.map().camera;
  const Rigid3d pose = map.map().keyframes[5].map_from_cam;
  const auto transparent = PredictTransparentWorld(map, camera, pose);
  const std::set<uint32_t> returned(transparent.begin(), transparent.end());
  int in_view = 0;
  for (size_t j = 0; j < map.point_count(); ++j) {
    Eigen::Vector2d pixel;
    const bool visible =
        camera.Project(pose.Inverse() * map.map().points[j].position_in_map, &pixel) &&
        camera.IsInImage(pixel);
    in_view += visible;
    EXPECT_EQ(returned.count(static_cast<uint32_t>(j)) > 0, visible) << j;
  }
  EXPECT_GT(in_view, 100);
  EXPECT_LT(in_view, static_cast<int>(map.point_count()));  // points behind are left out
}

TEST(VisibilityPredictorTest, RefusesAMapWithoutKernel) {
  Map map = TestMap();
  map.kernel.metric.resize(0, 0);
  const LocalizationMap localization(map);
  EXPECT_THROW(VisibilityPredictor(localization, VisibilityOptions{}), CheckError);
}

}  // namespace
}  // namespace visloc
