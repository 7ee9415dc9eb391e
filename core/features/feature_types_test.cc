#include "core/features/feature_types.h"

#include <gtest/gtest.h>

#include <limits>

#include "core/features/descriptor.h"
#include "core/features/descriptor_matching.h"
#include "core/util/check.h"

namespace visloc {
namespace {

TEST(DescriptorDistanceTest, HammingForBinaryAndL2ForFloat) {
  cv::Mat bits(2, 32, CV_8U, cv::Scalar(0));
  bits.at<uint8_t>(1, 0) = 0b1011;  // 3 bits differ
  bits.at<uint8_t>(1, 31) = 0xFF;   // 8 more
  EXPECT_FLOAT_EQ(DescriptorDistance(bits, 0, bits, 1), 11.0f);
  cv::Mat floats = (cv::Mat_<float>(2, 2) << 0.0f, 0.0f, 3.0f, 4.0f);
  EXPECT_FLOAT_EQ(DescriptorDistance(floats, 0, floats, 1), 5.0f);
  EXPECT_FLOAT_EQ(DescriptorDistance(floats, 1, floats, 1), 0.0f);
}

TEST(DescriptorDistanceTest, ColumnsFindTheSameNearestTwoBitForBit) {
  cv::Mat descriptors(37, 16, CV_32F);
  cv::randu(descriptors, -1.0f, 1.0f);
  // 35 rows: two groups of sixteen lanes and a remainder. Rows 12 (within a group, across the
  // groups and into the remainder) and 7 (in both groups) tie: the first index must win and its
  // twin be the second.
  const std::vector<uint32_t> rows = {5,  0,  36, 12, 12, 7,  30, 1,  2,  3,  33, 20,
                                      18, 9,  4,  31, 7,  12, 22, 26, 8,  10, 11, 13,
                                      14, 15, 16, 17, 19, 21, 23, 24, 12, 25, 27};
  const Float16Columns columns(descriptors, rows);
  ASSERT_EQ(columns.size(), static_cast<int>(rows.size()));
  int ties = 0;
  for (int query = 0; query < descriptors.rows; ++query) {
    NearestTwo expected;
    for (size_t j = 0; j < rows.size(); ++j) {
      expected.Offer(DescriptorDistance(descriptors, query, descriptors, static_cast<int>(rows[j])),
                     static_cast<int>(j));
    }
    const NearestTwo nearest = columns.Nearest(descriptors.ptr<float>(query));
    EXPECT_EQ(nearest.best_index, expected.best_index) << "query " << query;
    EXPECT_EQ(nearest.best, expected.best) << "query " << query;
    EXPECT_EQ(nearest.second, expected.second) << "query " << query;
    ties += expected.best == expected.second;
  }
  // Every query whose nearest row is listed more than once; at least 7 and 12 themselves.
  EXPECT_GE(ties, 2);
  EXPECT_THROW(Float16Columns(cv::Mat(3, 32, CV_8U), {0}), std::exception);
  EXPECT_THROW(Float16Columns(descriptors, {37}), std::exception);  // Past the last row.
}

TEST(GuidedMatchingTest, FindsTheNearestDescriptorWithinTheRadiusOnly) {
  // Keypoints along a row, 10 px apart; descriptors are one-hot, so each query has exactly one
  // keypoint at distance 0 and all others at sqrt(2).
  std::vector<Eigen::Vector2f> pixels;
  cv::Mat keypoint_descriptors(6, 16, CV_32F, cv::Scalar(0));
  for (int i = 0; i < 6; ++i) {
    pixels.emplace_back(20.0f + 10.0f * i, 30.0f);
    keypoint_descriptors.at<float>(i, i) = 1.0f;
  }
  const KeypointGrid grid(pixels, 100, 60, 16);
  int visited = 0;
  grid.ForEachWithin(Eigen::Vector2d(40, 30), 10.5, [&](int) { ++visited; });
  EXPECT_EQ(visited, 3);  // 30, 40 and 50 px

  const cv::Mat query_descriptors = keypoint_descriptors.clone();
  std::vector<GuidedQuery> queries = {
      {&query_descriptors, 2, Eigen::Vector2d(42, 31)},  // keypoint 2 at 40 px: found
      {&query_descriptors, 5, Eigen::Vector2d(20, 30)},  // keypoint 5 is 50 px away: not found
  };
  const std::vector<GuidedMatch> matches =
      MatchGuided(queries, grid, keypoint_descriptors, 15.0, DescriptorMatchOptions{});
  ASSERT_EQ(matches.size(), 1u);
  EXPECT_EQ(matches[0].query, 0);
  EXPECT_EQ(matches[0].keypoint, 2);
  EXPECT_FLOAT_EQ(matches[0].distance, 0.0f);
}

TEST(GuidedMatchingTest, OneQueryPerKeypointTheClosestWins) {
  const std::vector<Eigen::Vector2f> pixels = {{10, 10}, {50, 50}};
  cv::Mat keypoint_descriptors(2, 16, CV_32F, cv::Scalar(0));
  keypoint_descriptors.at<float>(0, 0) = 1.0f;
  keypoint_descriptors.at<float>(1, 1) = 1.0f;
  cv::Mat query_descriptors(2, 16, CV_32F, cv::Scalar(0));
  query_descriptors.at<float>(0, 0) = 0.9f;  // distance 0.1 to keypoint 0
  query_descriptors.at<float>(1, 0) = 0.8f;  // distance 0.2 to keypoint 0
  const KeypointGrid grid(pixels, 64, 64, 8);
  const std::vector<GuidedMatch> matches =
      MatchGuided({{&query_descriptors, 0, {10, 10}}, {&query_descriptors, 1, {11, 10}}}, grid,
                  keypoint_descriptors, 5.0, DescriptorMatchOptions{});
  ASSERT_EQ(matches.size(), 1u);
  EXPECT_EQ(matches[0].query, 0);
  EXPECT_NEAR(matches[0].distance, 0.1f, 1e-6);
}

// MatchGuided measures the neighbours of a prediction as squares, one at a time or, in runs of
// sixteen and more (here from 40 px on), sixteen at a time; it must choose what offering each
// DescriptorDistance in ForEachWithin's order chooses, ties and the distances' last bits
// included (the oracle below is that definition).
TEST(GuidedMatchingTest, MatchesAsOfferingEachDistanceInOrderBitForBit) {
  cv::RNG rng(3);
  constexpr int kKeypoints = 700, kQueries = 500;
  std::vector<Eigen::Vector2f> pixels;
  for (int i = 0; i < kKeypoints; ++i) {
    pixels.emplace_back(rng.uniform(0.0f, 320.0f), rng.uniform(0.0f, 240.0f));
  }
  cv::Mat keypoint_descriptors(kKeypoints, 16, CV_32F);
  rng.fill(keypoint_descriptors, cv::RNG::UNIFORM, 0.0f, 0.3f);
  // Look-alike twins (exact ties) and near twins, some close together in the image.
  for (int i = 0; i < kKeypoints; i += 7)
    keypoint_descriptors.row(i).copyTo(keypoint_descriptors.row(i + 1));
  for (int i = 3; i + 20 < kKeypoints; i += 11) {
    keypoint_descriptors.row(i).copyTo(keypoint_descriptors.row(i + 20));
    keypoint_descriptors.at<float>(i + 20, 5) += 1e-7f;
    pixels[i + 20] = pixels[i] + Eigen::Vector2f(3.0f, -2.0f);
  }
  cv::Mat query_descriptors(kQueries, 16, CV_32F);
  std::vector<GuidedQuery> queries;
  for (int q = 0; q < kQueries; ++q) {
    const int near = rng.uniform(0, kKeypoints);
    for (int d = 0; d < 16; ++d) {
      query_descriptors.at<float>(q, d) =
          keypoint_descriptors.at<float>(near, d) + rng.uniform(-0.05f, 0.05f) * (q % 3);
    }
    queries.push_back({&query_descriptors, q,
                       pixels[near].cast<double>() +
                           Eigen::Vector2d(rng.uniform(-8.0, 8.0), rng.uniform(-8.0, 8.0))});
  }
  const KeypointGrid grid(pixels, 320, 240, 16);
  const DescriptorMatchOptions options;
  const float max_distance = options.MaxDistance(DescriptorType::kFloat32);
  for (double radius_px : {4.0, 15.0, 40.0, 90.0}) {
    std::vector<GuidedMatch> claims(kKeypoints, {-1, 0, std::numeric_limits<float>::max()});
    for (int q = 0; q < kQueries; ++q) {
      NearestTwo nearest;
      grid.ForEachWithin(queries[q].pixel, radius_px, [&](int i) {
        nearest.Offer(DescriptorDistance(query_descriptors, q, keypoint_descriptors, i), i);
      });
      if (!nearest.Distinctive(options.ratio, max_distance)) continue;
      GuidedMatch& claim = claims[nearest.best_index];
      if (nearest.best < claim.distance) claim = {q, nearest.best_index, nearest.best};
    }
    std::vector<GuidedMatch> expected;
    for (const GuidedMatch& claim : claims) {
      if (claim.query >= 0) expected.push_back(claim);
    }
    const std::vector<GuidedMatch> matches =
        MatchGuided(queries, grid, keypoint_descriptors, radius_px, options);
    ASSERT_EQ(matches.size(), expected.size()) << radius_px << " px";
    EXPECT_GT(matches.size(), 50u);
    for (size_t m = 0; m < matches.size(); ++m) {
      EXPECT_EQ(matches[m].query, expected[m].query);
      EXPECT_EQ(matches[m].keypoint, expected[m].keypoint);
      EXPECT_EQ(matches[m].distance, expected[m].distance);
    }
  }
}

TEST(MutualNearestTest, KeepsPairsThatChooseEachOther) {
  cv::Mat a(3, 16, CV_32F, cv::Scalar(0)), b(3, 16, CV_32F, cv::Scalar(0));
  a.at<float>(0, 0) = 1;  // a0 ~ b1
  b.at<float>(1, 0) = 0.95f;
  a.at<float>(1, 1) = 1;  // a1 ~ b0, but a2 is as close to b0: b0's choice is ambiguous
  a.at<float>(2, 1) = 0.98f;
  a.at<float>(2, 3) = 0.02f;
  b.at<float>(0, 1) = 0.99f;
  b.at<float>(0, 3) = 0.01f;
  b.at<float>(2, 2) = 1;  // b2 matches nothing
  const auto pairs = MatchMutualNearest(a, b, DescriptorMatchOptions{});
  ASSERT_EQ(pairs.size(), 1u);
  EXPECT_EQ(pairs[0], std::make_pair(0, 1));
  EXPECT_TRUE(MatchMutualNearest(cv::Mat(), b, DescriptorMatchOptions{}).empty());
}

TEST(DescriptorMatchOptionsTest, RefusesRatiosAndDistancesOutOfRange) {
  DescriptorMatchOptions options;
  EXPECT_NO_THROW(options.Check());
  options.ratio = 1.5f;
  EXPECT_THROW(options.Check(), CheckError);
  options = {};
  options.max_float_distance = -1.0f;
  EXPECT_THROW(options.Check(), CheckError);
}

}  // namespace
}  // namespace visloc
