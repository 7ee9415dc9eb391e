#include "sim/texture.h"

#include <gtest/gtest.h>

namespace visloc::sim {
namespace {

TEST(TextureTest, GenerationIsDeterministicInTheSeed) {
  const cv::Mat a = GenerateTexture(TextureStyle::kPosterWall, 1.0, 0.8, 0.004, 3);
  const cv::Mat b = GenerateTexture(TextureStyle::kPosterWall, 1.0, 0.8, 0.004, 3);
  const cv::Mat c = GenerateTexture(TextureStyle::kPosterWall, 1.0, 0.8, 0.004, 4);
  EXPECT_EQ(a.size(), cv::Size(250, 200));
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0);
  EXPECT_GT(cv::norm(a, c, cv::NORM_L1), 0.0);
}

TEST(TextureTest, RichStylesHaveContrastAndPlainHasNone) {
  cv::Scalar mean, stddev;
  cv::meanStdDev(GenerateTexture(TextureStyle::kPosterWall, 3.0, 2.0, 0.004, 1), mean, stddev);
  EXPECT_GT(stddev[0], 25.0);
  cv::meanStdDev(GenerateTexture(TextureStyle::kPlain, 3.0, 2.0, 0.004, 1), mean, stddev);
  EXPECT_LT(stddev[0], 6.0);
}

TEST(TextureTest, LargeFootprintAveragesFineDetail) {
  // A one-texel checkerboard: sharp up close, mid-grey when a sample covers many texels.
  cv::Mat checker(64, 64, CV_8UC1);
  for (int r = 0; r < 64; ++r) {
    for (int c = 0; c < 64; ++c) checker.at<uint8_t>(r, c) = ((r + c) % 2) ? 255 : 0;
  }
  const Texture texture(checker, 0.01);
  EXPECT_NEAR(texture.Sample(0.005, 0.005, 0.001), 0.0, 1e-6);  // texel (0, 0) centre
  EXPECT_NEAR(texture.Sample(0.015, 0.005, 0.001), 1.0, 1e-6);
  EXPECT_NEAR(texture.Sample(0.3, 0.3, 0.16), 0.5, 0.02);
}

TEST(TextureTest, DetailStaysInPlaceAtEveryMipLevel) {
  // Odd sizes do not halve exactly (750 -> 375 -> 187 -> 93): a regression test for features
  // that slid across coarse mip levels, which made a camera walking closer see apparent motion.
  constexpr double kTexel = 0.004;
  cv::Mat albedo(750, 101, CV_8UC1, cv::Scalar(220));
  albedo.rowRange(598, 602).setTo(cv::Scalar(20));  // a dark line centred at v = 600 texels
  const Texture texture(albedo, kTexel);
  const double expected_v = 600.0 * kTexel;
  for (double footprint : {0.001, 0.009, 0.017, 0.033, 0.065}) {
    double sum = 0, weighted = 0;
    for (double v = expected_v - 0.3; v <= expected_v + 0.3; v += 0.0005) {
      const double darkness = 1.0 - texture.Sample(0.2, v, footprint);
      sum += darkness;
      weighted += darkness * v;
    }
    EXPECT_NEAR(weighted / sum, expected_v, 0.25 * kTexel) << "footprint " << footprint;
  }
}

}  // namespace
}  // namespace visloc::sim
