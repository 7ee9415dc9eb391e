#include "core/map/map.h"

#include <map>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "core/map/localization_map.h"
#include "core/map/synthetic_map.h"
#include "core/map/vocabulary.h"
#include "core/util/check.h"

namespace visloc {
namespace {

using ::testing::ElementsAre;
using ::testing::HasSubstr;

TEST(MapTest, SyntheticMapIsConsistent) {
  for (DescriptorType type : {DescriptorType::kFloat32, DescriptorType::kBinary}) {
    SyntheticMapOptions options;
    options.descriptor_type = type;
    options.descriptor_dim = type == DescriptorType::kFloat32 ? 16 : 32;
    const Map map = MakeSyntheticMap(options);
    EXPECT_THAT(FindMapProblems(map), ::testing::IsEmpty());
    EXPECT_EQ(map.observations.size(), 40000u);
    EXPECT_TRUE(MapsEqual(map, MakeSyntheticMap(options)));
  }
}

TEST(MapTest, FindsEachKindOfProblem) {
  SyntheticMapOptions options;
  options.keyframes = 10;
  options.points = 50;
  const Map good = MakeSyntheticMap(options);

  Map nan_pose = good;
  nan_pose.keyframes[3].map_from_cam.translation.x() = std::nan("");
  EXPECT_THAT(FindMapProblems(nan_pose),
              ElementsAre("keyframe 3 has a non-finite pose or a non-unit quaternion"));

  Map dangling = good;
  dangling.observations.back().point = 999;
  EXPECT_THAT(FindMapProblems(dangling),
              ::testing::Contains(HasSubstr("refers to keyframe 9 and point 999")));

  Map short_descriptors = good;
  short_descriptors.descriptors = good.descriptors.rowRange(0, 10).clone();
  EXPECT_THAT(FindMapProblems(short_descriptors), ElementsAre("50 points but 10 descriptors"));

  Map miscounted = good;
  miscounted.points[7].observation_count = 9;
  EXPECT_THAT(FindMapProblems(miscounted), ElementsAre("point 7 claims 9 observations but has 4"));

  Map bad_kernel = good;
  bad_kernel.kernel.metric = Eigen::Matrix3d::Identity();
  EXPECT_THAT(FindMapProblems(bad_kernel),
              ElementsAre("visibility kernel metric is 3x3 for 2 cues"));
  EXPECT_FALSE(MapsEqual(good, bad_kernel));
}

TEST(LocalizationMapTest, VisibilityListsMatchTheObservations) {
  SyntheticMapOptions options;
  options.keyframes = 20;
  options.points = 300;
  const Map map = MakeSyntheticMap(options);
  const LocalizationMap localization(map);
  size_t total = 0;
  for (size_t k = 0; k < localization.keyframe_count(); ++k) {
    std::vector<uint32_t> expected;
    for (const Observation& o : map.observations) {
      if (o.keyframe == k) expected.push_back(o.point);
    }
    const auto visible = localization.VisiblePoints(k);
    EXPECT_EQ(std::vector<uint32_t>(visible.begin(), visible.end()), expected);
    total += visible.size();
  }
  EXPECT_EQ(total, map.observations.size());
  EXPECT_TRUE(localization.keyframe_view_dirs()[0].isApprox(Eigen::Vector3d(1, 0, 0)));
  EXPECT_GT(localization.MemoryBytes(), 300u * (32 + 64));
  EXPECT_EQ(LocalizationMap::MemoryBytesFor(map), localization.MemoryBytes());
  Map broken = map;
  broken.points.pop_back();
  EXPECT_THROW(LocalizationMap{broken}, CheckError);
}

TEST(LocalizationMapTest, InvertedIndexScoresEqualTheDirectScores) {
  SyntheticMapOptions options;
  options.keyframes = 30;
  options.points = 600;
  const Map map = MakeSyntheticMap(options);
  const LocalizationMap localization(map);
  ASSERT_TRUE(localization.has_appearance_index());
  for (size_t q : {0u, 7u, 29u}) {
    const BowVector& query = map.appearance.keyframe_vectors[q];
    const std::vector<float> scores = localization.ScoreKeyframes(query);
    ASSERT_EQ(scores.size(), map.keyframes.size());
    for (size_t k = 0; k < scores.size(); ++k) {
      EXPECT_NEAR(scores[k], BowScore(query, map.appearance.keyframe_vectors[k]), 1e-5) << k;
    }
    EXPECT_NEAR(scores[q], 1.0, 1e-5);
  }
}

// Posting lists store keyframe gaps in 16 bits; a gap beyond that is escaped.
TEST(LocalizationMapTest, KeyframesFarApartInAWordsPostingListScoreExactly) {
  SyntheticMapOptions options;
  options.keyframes = 70002;
  options.points = 70002;
  options.observations_per_point = 1;
  options.vocabulary_depth = 1;
  Map map = MakeSyntheticMap(options);
  for (BowVector& v : map.appearance.keyframe_vectors) v = {{1, 1.0f}};
  map.appearance.keyframe_vectors[0] = {{3, 1.0f}};
  map.appearance.keyframe_vectors[5] = {{3, 0.5f}, {4, 0.5f}};
  map.appearance.keyframe_vectors[70001] = {{3, 0.25f}, {4, 0.75f}};
  const LocalizationMap localization(map);
  const std::vector<float> scores = localization.ScoreKeyframes({{3, 1.0f}});
  EXPECT_EQ(scores[0], 1.0f);
  EXPECT_EQ(scores[5], 0.5f);
  EXPECT_EQ(scores[70001], 0.25f);
  EXPECT_EQ(scores[70000], 0.0f);
  EXPECT_EQ(localization.ScoreKeyframes({{4, 0.6f}})[70001], 0.6f);
}

}  // namespace
}  // namespace visloc

namespace visloc {
namespace {

// A random vocabulary of `branching` and `depth` over 16-float (or 32-byte binary) descriptors,
// with two children of one node equal, so that lookups meet exact ties.
Vocabulary RandomVocabulary(int branching, int depth, bool binary) {
  Vocabulary vocabulary;
  vocabulary.branching = branching;
  vocabulary.depth = depth;
  int nodes = 0, words = 1;
  for (int level = 0; level < depth; ++level) nodes += (words *= branching);
  vocabulary.centroids =
      binary ? cv::Mat(nodes, 32, CV_8U) : cv::Mat(nodes, 16, CV_32F);
  cv::RNG rng(5);
  if (binary) {
    rng.fill(vocabulary.centroids, cv::RNG::UNIFORM, 0, 256);
  } else {
    rng.fill(vocabulary.centroids, cv::RNG::UNIFORM, -1.0, 1.0);
  }
  vocabulary.centroids.row(3).copyTo(vocabulary.centroids.row(1));  // A tie at the first level.
  for (int w = 0; w < words; ++w) vocabulary.word_weights.push_back(0.5f + 0.01f * (w % 7));
  return vocabulary;
}

// The batched lookup (eight children at a time for 16 floats) gives LookupWord's words, ties
// included, and ComputeBow the vector one lookup at a time would.
TEST(VocabularyTest, BatchedLookupGivesEachDescriptorsWord) {
  for (const bool binary : {false, true}) {
    for (const int branching : {8, 10}) {
      const Vocabulary vocabulary = RandomVocabulary(branching, 3, binary);
      cv::Mat descriptors = binary ? cv::Mat(300, 32, CV_8U) : cv::Mat(300, 16, CV_32F);
      cv::RNG rng(9);
      if (binary) {
        rng.fill(descriptors, cv::RNG::UNIFORM, 0, 256);
      } else {
        rng.fill(descriptors, cv::RNG::UNIFORM, -1.0, 1.0);
      }
      vocabulary.centroids.row(1).copyTo(descriptors.row(0));  // On the tie itself.
      const std::vector<uint32_t> words = LookupWords(vocabulary, descriptors);
      ASSERT_EQ(words.size(), 300u);
      std::map<uint32_t, float> counts;
      for (int r = 0; r < descriptors.rows; ++r) {
        EXPECT_EQ(words[r], LookupWord(vocabulary, descriptors, r)) << "row " << r;
        counts[words[r]] += 1.0f;
      }
      EXPECT_EQ(words[0] / (branching * branching), 1u);  // The first of the tied children.
      BowVector expected;
      float total = 0;
      for (const auto& [word, count] : counts) {
        expected.emplace_back(word, count * vocabulary.word_weights[word]);
        total += expected.back().second;
      }
      for (auto& [word, weight] : expected) weight /= total;
      EXPECT_EQ(ComputeBow(vocabulary, descriptors), expected);
    }
  }
}

}  // namespace
}  // namespace visloc
