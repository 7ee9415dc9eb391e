#include "mapping/site_alignment.h"

#include <gtest/gtest.h>

#include "core/util/random.h"

namespace visloc::mapping {
namespace {

// A site frame turned and moved against the map, spots surveyed with `noise_m` per axis.
const Rigid3d kSiteFromMap(
    Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Eigen::Vector3d(0.1, -1, 0.3).normalized())),
    Eigen::Vector3d(12.0, -3.5, 0.8));

std::vector<PositionPair> Spots(int n, double noise_m) {
  Rng rng(7);
  std::vector<PositionPair> pairs;
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d in_map(rng.Uniform(-4, 4), rng.Uniform(-0.2, 0.2), rng.Uniform(0, 8));
    Eigen::Vector3d in_site = kSiteFromMap * in_map;
    for (int a = 0; a < 3; ++a) in_site[a] += rng.Normal(0, noise_m);
    pairs.push_back({"spot " + std::to_string(i + 1), in_map, in_site});
  }
  return pairs;
}

TEST(SiteAlignmentTest, SurveyedSpotsGiveTheSiteFrameWithEachPairsResidual) {
  const SiteAlignResult result = AlignToSite(Spots(6, 0.01), std::nullopt, "pairs spots.csv");
  ASSERT_TRUE(result.site) << result.why_not;
  EXPECT_EQ(result.site->pairs, 6);
  EXPECT_EQ(result.site->reference, "pairs spots.csv");
  EXPECT_LT(result.site->rms_m, 0.03);
  EXPECT_GE(result.site->max_residual_m, result.site->rms_m);
  ASSERT_EQ(result.residuals_m.size(), 6u);
  ASSERT_EQ(result.left_out_residuals_m.size(), 6u);
  for (const Eigen::Vector3d& corner : {Eigen::Vector3d(-4, 0, 0), Eigen::Vector3d(4, 0, 8)}) {
    EXPECT_LT((result.site->site_from_map * corner - kSiteFromMap * corner).norm(), 0.03);
  }
  EXPECT_FALSE(result.site_z_from_up_deg);  // The map knows no up.
}

TEST(SiteAlignmentTest, AWrongPairIsNamedAndTheFitRefused) {
  std::vector<PositionPair> pairs = Spots(5, 0.01);
  pairs[3].in_site.x() += 1.0;
  const SiteAlignResult result = AlignToSite(pairs, std::nullopt, "pairs");
  EXPECT_FALSE(result.site);
  EXPECT_EQ(result.why_not.rfind("pair 'spot 4' is ", 0), 0u) << result.why_not;
  EXPECT_NE(result.why_not.find("a wrong pair?"), std::string::npos);
  EXPECT_GT(result.left_out_residuals_m[3], 0.9);
}

TEST(SiteAlignmentTest, TooFewPairsOrPairsOnALineAreRefusedWithTheReason) {
  EXPECT_EQ(AlignToSite(Spots(2, 0.0), std::nullopt, "").why_not,
            "2 position pairs; a rigid fit needs 3");
  std::vector<PositionPair> line;
  for (int i = 0; i < 5; ++i) {
    const Eigen::Vector3d in_map(i, 0, 0);
    line.push_back({"p", in_map, kSiteFromMap * in_map});
  }
  EXPECT_NE(AlignToSite(line, std::nullopt, "").why_not.find("the pairs lie on a line"),
            std::string::npos);
}

TEST(SiteAlignmentTest, TheSitesZIsComparedWithTheMapsUp) {
  // The map's up is the site's z turned into the map: 0 deg apart.
  const MapGravity gravity{kSiteFromMap.rotation.inverse() * Eigen::Vector3d::UnitZ(), 0.1,
                           MapGravity::Source::kImu};
  const SiteAlignResult result = AlignToSite(Spots(5, 0.0), gravity, "pairs");
  ASSERT_TRUE(result.site_z_from_up_deg);
  EXPECT_LT(*result.site_z_from_up_deg, 1e-6);
}

TEST(SiteAlignmentTest, TrajectoriesPairByStamp) {
  Trajectory map_from_cam, site_from_cam;
  for (int i = 0; i < 10; ++i) {
    const Rigid3d pose(Eigen::Quaterniond::Identity(), Eigen::Vector3d(i, 0, 0));
    map_from_cam.push_back({i * 100'000'000LL, pose});
    // The reference 4 ms late, every other stamp missing.
    if (i % 2 == 0) site_from_cam.push_back({i * 100'000'000LL + 4'000'000, kSiteFromMap * pose});
  }
  const std::vector<PositionPair> pairs = PairsFromTrajectories(map_from_cam, site_from_cam);
  ASSERT_EQ(pairs.size(), 5u);
  EXPECT_EQ(pairs[1].name, "t = 0.200 s");
  EXPECT_TRUE(pairs[1].in_site.isApprox(kSiteFromMap * Eigen::Vector3d(2, 0, 0)));
}

}  // namespace
}  // namespace visloc::mapping
