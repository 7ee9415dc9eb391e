#include "mapping/map_merge.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>

#include <Eigen/Geometry>

#include "core/map/localization_map.h"
#include "core/map/synthetic_map.h"
#include "core/map/vocabulary.h"
#include "core/util/check.h"
#include "core/util/random.h"

namespace visloc::mapping {
namespace {

// The session of `a`'s keyframes [first, last) and the points they see, in a frame of its own
// (`b_from_a`), positions perturbed by `noise_m`; `a_point_of_b` tells where each point came from.
Map Session(const Map& a, uint32_t first, uint32_t last, const Rigid3d& b_from_a, double noise_m,
            std::vector<int>* a_point_of_b = nullptr) {
  Rng rng(7);
  Map b;
  b.metadata = {"tuesday", 1, "/data/tue", "test", ""};
  b.camera = a.camera;
  b.features = a.features;
  for (size_t k = first; k < last; ++k) {
    b.keyframes.push_back({a.keyframes[k].timestamp_ns, b_from_a * a.keyframes[k].map_from_cam});
  }
  std::vector<int> point_of_a(a.points.size(), -1);
  for (const Observation& o : a.observations) {
    if (o.keyframe < first || o.keyframe >= last) continue;
    if (point_of_a[o.point] < 0) {
      point_of_a[o.point] = static_cast<int>(b.points.size());
      MapPoint p = a.points[o.point];
      p.position_in_map = b_from_a * p.position_in_map +
                          noise_m * Eigen::Vector3d(rng.Uniform(-1, 1), rng.Uniform(-1, 1), rng.Uniform(-1, 1));
      b.points.push_back(p);
      b.descriptors.push_back(a.descriptors.row(o.point));
      if (a_point_of_b) a_point_of_b->push_back(static_cast<int>(o.point));
    }
    b.observations.push_back({o.keyframe - first, static_cast<uint32_t>(point_of_a[o.point]), o.pixel});
  }
  for (MapPoint& p : b.points) p.observation_count = 0;
  for (const Observation& o : b.observations) ++b.points[o.point].observation_count;
  return b;
}

// Map B: the second half of A's keyframes, in a frame of its own.
Map SecondSession(const Map& a, const Rigid3d& b_from_a, double noise_m,
                  std::vector<int>* a_point_of_b = nullptr) {
  return Session(a, static_cast<uint32_t>(a.keyframes.size() / 2),
                 static_cast<uint32_t>(a.keyframes.size()), b_from_a, noise_m, a_point_of_b);
}

// MakeSyntheticMap's maps observe points outside the image (they are made for storage tests),
// which no bundle adjustment can fit: these tests check registration and fusion, and
// map_adjustment_test checks the adjustment.
MergeOptions RigidOnlyMerge() {
  MergeOptions options;
  options.skip_adjustment = true;
  return options;
}

Map MondayMap(uint64_t seed) {
  SyntheticMapOptions options;
  options.keyframes = 40;
  options.points = 3000;
  options.seed = seed;
  Map map = MakeSyntheticMap(options);
  map.metadata.name = "monday";
  return map;
}

TEST(MapMergeTest, RecoversTheSecondSessionsFrameAndFusesItsPoints) {
  const Map a = MondayMap(1);
  const Rigid3d b_from_a(Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d(0.2, 1, 0.1).normalized())),
                         Eigen::Vector3d(3.0, -1.0, 0.5));
  Map b = SecondSession(a, b_from_a, 0.005);
  // Only B's build recorded the rig's disparity correction (the rig is the same: one camera).
  b.metadata.disparity_correction = DisparityCorrection{0.1, 2e-4};
  MergeStats stats;
  const Map merged = MergeMaps(a, b, RigidOnlyMerge(), &stats);
  EXPECT_EQ(merged.metadata.disparity_correction, b.metadata.disparity_correction);
  EXPECT_TRUE(ApproxEqual(stats.a_from_b, b_from_a.Inverse(), 0.005, 0.2));
  EXPECT_GT(stats.fused_points, 0.9 * b.points.size());
  EXPECT_EQ(stats.fused_points + stats.added_points, static_cast<int>(b.points.size()));
  EXPECT_EQ(merged.keyframes.size(), a.keyframes.size() + b.keyframes.size());
  EXPECT_EQ(merged.points.size(), a.points.size() + stats.added_points);
  // B's keyframes land on A's.
  const size_t first = a.keyframes.size() / 2;
  for (size_t k = 0; k < b.keyframes.size(); ++k) {
    EXPECT_TRUE(ApproxEqual(merged.keyframes[a.keyframes.size() + k].map_from_cam,
                            a.keyframes[first + k].map_from_cam, 0.005, 0.2));
  }
  EXPECT_TRUE(FindMapProblems(merged).empty());
  EXPECT_EQ(merged.appearance.keyframe_vectors.size(), merged.keyframes.size());
  EXPECT_EQ(merged.metadata.lineage,
            "merge('monday' <- synthetic; 'tuesday' <- /data/tue)");
}

// Up: the better known of the two maps', B's turned into A's frame.
TEST(MapMergeTest, TheMergedMapKeepsTheBetterKnownUpInItsOwnFrame) {
  const Map a = MondayMap(1);
  const Rigid3d b_from_a(
      Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d(0.2, 1, 0.1).normalized())),
      Eigen::Vector3d(3.0, -1.0, 0.5));
  const Eigen::Vector3d up_in_a = Eigen::Vector3d(0.1, -0.95, -0.3).normalized();
  Map b = SecondSession(a, b_from_a, 0.005);
  b.metadata.gravity = MapGravity{b_from_a.rotation * up_in_a, 0.05, MapGravity::Source::kImu};
  Map a_floor = a;
  a_floor.metadata.gravity = MapGravity{Eigen::Vector3d(0, -1, 0), 1.0, MapGravity::Source::kFloor};
  for (const Map* first : {&a, static_cast<const Map*>(&a_floor)}) {
    MergeStats stats;
    const Map merged = MergeMaps(*first, b, RigidOnlyMerge(), &stats);
    ASSERT_TRUE(merged.metadata.gravity);
    EXPECT_EQ(merged.metadata.gravity->source, MapGravity::Source::kImu);
    EXPECT_LT((merged.metadata.gravity->up_in_map - up_in_a).norm(), 0.005);
    EXPECT_TRUE(FindMapProblems(merged).empty());
  }
  // A's own, when it is the better known.
  b.metadata.gravity->sigma_deg = 2.0;
  MergeStats stats;
  EXPECT_EQ(MergeMaps(a_floor, b, RigidOnlyMerge(), &stats).metadata.gravity,
            a_floor.metadata.gravity);
}

TEST(MapMergeTest, AFusedPointLiesHalfwayBetweenItsTwoMapsEstimates) {
  const Map a = MondayMap(1);
  const Rigid3d b_from_a(Eigen::Quaterniond(Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitZ())),
                         Eigen::Vector3d(0.5, 0.0, 0.0));
  std::vector<int> a_point_of_b;
  const Map b = SecondSession(a, b_from_a, 0.005, &a_point_of_b);
  MergeStats stats;
  const Map merged = MergeMaps(a, b, RigidOnlyMerge(), &stats);
  int halfway = 0;
  for (size_t q = 0; q < b.points.size(); ++q) {
    const int p = a_point_of_b[q];
    const Eigen::Vector3d mean =
        0.5 * (a.points[p].position_in_map + stats.a_from_b * b.points[q].position_in_map);
    halfway += (merged.points[p].position_in_map - mean).norm() < 1e-9;
  }
  EXPECT_GT(halfway, 0.9 * b.points.size());
}

TEST(MapMergeTest, NearAGuessTheFrameIsRefinedFromThePointsAlone) {
  const Map a = MondayMap(1);
  const Rigid3d b_from_a(
      Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d(0.2, 1, 0.1).normalized())),
      Eigen::Vector3d(3.0, -1.0, 0.5));
  const Map b = SecondSession(a, b_from_a, 0.005);
  // Where localizing B's images in A would put it: a centimetre and a tenth of a degree off.
  const Rigid3d a_from_b = b_from_a.Inverse();
  const Rigid3d guess =
      Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(0.002, Eigen::Vector3d::UnitY())),
              Eigen::Vector3d(0.01, -0.005, 0.005)) *
      a_from_b;
  MergeStats stats;
  const Map merged = MergeMaps(a, b, RigidOnlyMerge(), &stats, guess);
  EXPECT_TRUE(stats.from_guess);
  EXPECT_TRUE(ApproxEqual(stats.a_from_b, a_from_b, 0.002, 0.05));
  EXPECT_GT(stats.fused_points, 0.9 * b.points.size());
  EXPECT_TRUE(FindMapProblems(merged).empty());
  // A guess a metre off finds no look-alike points where it puts B: refused, not forced.
  const Rigid3d far_off =
      Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(1, 0, 0)) * a_from_b;
  try {
    MergeMaps(a, b, RigidOnlyMerge(), &stats, far_off);
    FAIL() << "merged at a placement where nothing meets";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("do not meet"));
  }
}

TEST(MapMergeTest, WhatOnlyBSawIsFoundByAppearanceInTheMergedMap) {
  // One walk of 60 keyframes: A mapped the first 40, B keyframes 30-59, so 40-59 are new.
  SyntheticMapOptions synthetic;
  synthetic.keyframes = 60;
  synthetic.points = 4500;
  const Map walk = MakeSyntheticMap(synthetic);
  const Map a = Session(walk, 0, 40, Rigid3d(), 0.0);
  const Map b =
      Session(walk, 30, 60,
              Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitZ())),
                      Eigen::Vector3d(1.0, 0.5, 0.0)),
              0.003);
  MergeStats stats;
  const LocalizationMap merged(MergeMaps(a, b, RigidOnlyMerge(), &stats));
  // The points the walk's last keyframe saw, as a query image would describe them.
  cv::Mat query;
  for (const Observation& o : walk.observations) {
    if (o.keyframe == 59) query.push_back(walk.descriptors.row(o.point));
  }
  const std::vector<float> scores =
      merged.ScoreKeyframes(ComputeBow(merged.map().appearance.vocabulary, query));
  const int best =
      static_cast<int>(std::max_element(scores.begin(), scores.end()) - scores.begin());
  EXPECT_EQ(best, 40 + 29) << "the merged map's best keyframe for the new place";
}

TEST(MapMergeTest, DuplicatesOfRepeatedTexturesAreFusedToo) {
  // Every fifth point's texture is repeated 5 m away in A (a poster printed twice), and the twin
  // looks even more like B's view of it than the original does: descriptor matching pairs B's
  // point with the twin (an outlier of the alignment), yet B's point lies on the original.
  const Map original = MondayMap(1);
  const Rigid3d b_from_a(Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ())),
                         Eigen::Vector3d(1.0, 2.0, 0.0));
  std::vector<int> a_point_of_b;
  Map b = SecondSession(original, b_from_a, 0.002, &a_point_of_b);
  Map a = original;
  Rng rng(11);
  for (size_t q = 0; q < b.points.size(); q += 5) {
    float* d = b.descriptors.ptr<float>(static_cast<int>(q));
    for (int i = 0; i < b.descriptors.cols; ++i) d[i] += static_cast<float>(rng.Uniform(-0.02, 0.02));
    MapPoint twin = original.points[a_point_of_b[q]];
    twin.position_in_map += Eigen::Vector3d(5, 5, 5);
    a.points.push_back(twin);
    a.descriptors.push_back(b.descriptors.row(static_cast<int>(q)));
    a.observations.push_back({0, static_cast<uint32_t>(a.points.size() - 1), Eigen::Vector2f(1, 1)});
    a.points.back().observation_count = 1;
  }
  std::sort(a.observations.begin(), a.observations.end(), [](const Observation& x, const Observation& y) {
    return x.keyframe != y.keyframe ? x.keyframe < y.keyframe : x.point < y.point;
  });
  MergeStats stats;
  const Map merged = MergeMaps(a, b, RigidOnlyMerge(), &stats);
  EXPECT_LT(stats.inliers, 0.85 * b.points.size());  // The repeated ones match their twins...
  EXPECT_GT(stats.fused_points, 0.95 * b.points.size());  // ...but fused all the same.
  EXPECT_TRUE(FindMapProblems(merged).empty());
}

TEST(MapMergeTest, MapsOfDifferentPlacesAreRefused) {
  const Map a = MondayMap(1);
  Map elsewhere = MondayMap(2);  // Other points, other descriptors.
  MergeStats stats;
  try {
    MergeMaps(a, elsewhere, RigidOnlyMerge(), &stats);
    FAIL() << "merged maps with nothing in common";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("no verified overlap"));
  }
  // The same descriptors in a scrambled geometry (same texture, another room) are refused too.
  Map scrambled = a;
  Rng rng(3);
  for (MapPoint& p : scrambled.points) {
    p.position_in_map = Eigen::Vector3d(rng.Uniform(-5, 5), rng.Uniform(-5, 5), rng.Uniform(-5, 5));
  }
  EXPECT_THROW(MergeMaps(a, scrambled, RigidOnlyMerge(), &stats), InputError);
}

TEST(MapMergeTest, MapsOfDifferentCamerasOrFeaturesAreRefused) {
  const Map a = MondayMap(1);
  Map other_camera = a;
  other_camera.camera = Camera(a.camera.width(), a.camera.height(), a.camera.fx() * 1.1,
                               a.camera.fy(), a.camera.cx(), a.camera.cy());
  MergeStats stats;
  EXPECT_THROW(MergeMaps(a, other_camera, RigidOnlyMerge(), &stats), InputError);
  Map other_features = a;
  other_features.features.kind = "orb";
  EXPECT_THROW(MergeMaps(a, other_features, RigidOnlyMerge(), &stats), InputError);
}

TEST(MapMergeTest, TheAdjustmentHoldsTheFrameAndWhatLiesBeyondTheSeam) {
  // A: keyframes 0-3; B: 4-5. Point 0 is seen by A's 1 and B's 4, point 1 by A's 2 alone, point
  // 2 by A's 3 and B's 5.
  Map merged;
  merged.keyframes.resize(6);
  merged.points.resize(3);
  const Eigen::Vector2f pixel = Eigen::Vector2f::Zero();
  merged.observations = {{1, 0, pixel}, {2, 1, pixel}, {3, 2, pixel}, {4, 0, pixel}, {5, 2, pixel}};
  EXPECT_EQ(KeyframesHeldInMergeAdjustment(merged, 4),
            std::vector<bool>({true, false, true, false, false, false}));
}

}  // namespace
}  // namespace visloc::mapping
