#include "core/features/features.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <set>

#include "core/features/harris_surf16.h"
#include "core/util/check.h"
#include "sim/renderer.h"
#include "sim/sequences.h"

namespace visloc {
namespace {

// Two views of the simulated room 5 cm apart, with the first view's depth.
struct ViewPair {
  PinholeCamera camera;
  cv::Mat first, second, first_depth;
  Rigid3d world_from_first, world_from_second;
};

const ViewPair& Views() {
  static const ViewPair views = [] {
    ViewPair v;
    const sim::StereoRig rig = sim::MakeRig(sim::RigOptions{});
    v.camera = rig.left.camera;
    sim::RoomOptions room;
    room.texel_m = 0.006;
    const sim::World world = sim::MakeRoom(room);
    const sim::Renderer renderer(v.camera, 2);
    const Rigid3d body(RotationFromRollPitchYaw(0, 0.05, 0.3), Eigen::Vector3d(0.2, -0.4, 1.45));
    v.world_from_first = body * rig.left.body_from_cam;
    v.world_from_second = v.world_from_first * Rigid3d(RotationFromRollPitchYaw(0.0, 0.02, 0.0),
                                                       Eigen::Vector3d(0.05, 0.0, 0.03));
    sim::SensorModel sensor;
    Rng noise(3);
    v.first = sensor.Capture(
        renderer.RenderRadiance(world, v.world_from_first, 0.0, &v.first_depth), &noise);
    v.second = sensor.Capture(renderer.RenderRadiance(world, v.world_from_second, 0.0), &noise);
    return v;
  }();
  return views;
}

// Where a keypoint of the first view must appear in the second, from the rendered depth.
bool Transfer(const ViewPair& v, const Keypoint& k, Eigen::Vector2d* pixel) {
  const float depth = v.first_depth.at<float>(static_cast<int>(std::lround(k.pixel.y())),
                                              static_cast<int>(std::lround(k.pixel.x())));
  if (depth <= 0) return false;
  const Eigen::Vector3d in_first = depth * v.camera.Unproject(k.pixel.cast<double>());
  return v.camera.Project(v.world_from_second.Inverse() * (v.world_from_first * in_first), pixel);
}

class FeatureKindTest : public ::testing::TestWithParam<std::string> {};

TEST_P(FeatureKindTest, EvenlySpreadRepeatableAndMatchable) {
  const ViewPair& v = Views();
  const auto extractor = CreateFeatureExtractor(DefaultFeatureSettings(GetParam()));
  ExtractStats stats;
  const FeatureSet a = extractor->Extract(v.first, &stats);
  const FeatureSet b = extractor->Extract(v.second);
  EXPECT_GE(a.size(), 300u);
  EXPECT_LE(a.size(), 600u);
  EXPECT_EQ(a.descriptors.rows, static_cast<int>(a.size()));
  EXPECT_EQ(a.descriptors.cols, extractor->settings().descriptor_dim);
  std::set<int> cells;
  for (const Keypoint& k : a.keypoints)
    cells.insert(static_cast<int>(k.pixel.y() / 40) * 8 + static_cast<int>(k.pixel.x() / 40));
  EXPECT_GE(cells.size(), 32u) << "features must cover most of the 8x6 grid";

  // Repeatability: the share of first-view corners detected again within 1.5 px of where the
  // true geometry puts them, and the accuracy of those positions. Then matching precision:
  // nearest-descriptor matches (with a ratio test) that land on the right corner.
  int transferable = 0, repeated = 0, matched = 0, correct = 0;
  std::vector<double> errors;
  for (size_t i = 0; i < a.size(); ++i) {
    Eigen::Vector2d expected;
    if (!Transfer(v, a.keypoints[i], &expected) || !v.camera.IsInImage(expected, 10)) continue;
    ++transferable;
    double nearest = 1e9;
    for (const Keypoint& k : b.keypoints)
      nearest = std::min(nearest, (k.pixel.cast<double>() - expected).norm());
    if (nearest < 1.5) {
      ++repeated;
      errors.push_back(nearest);
    }
    NearestTwo candidates;
    for (int j = 0; j < static_cast<int>(b.size()); ++j) {
      if ((b.keypoints[j].pixel.cast<double>() - expected).norm() > 30) continue;  // search window
      candidates.Offer(DescriptorDistance(a.descriptors, static_cast<int>(i), b.descriptors, j), j);
    }
    const int best_j = candidates.best_index;
    if (candidates.Distinctive(0.8f, std::numeric_limits<float>::max())) {
      ++matched;
      if ((b.keypoints[best_j].pixel.cast<double>() - expected).norm() < 2.0) ++correct;
    }
  }
  std::sort(errors.begin(), errors.end());
  const double repeatability = static_cast<double>(repeated) / transferable;
  const double precision = static_cast<double>(correct) / matched;
  std::printf(
      "%s: %zu features (%d detected), repeatability %.2f, median error %.2f px, "
      "%d matches with precision %.2f; detect %.2f ms, describe %.2f ms\n",
      GetParam().c_str(), a.size(), stats.detected, repeatability, errors[errors.size() / 2],
      matched, precision, stats.detect_ms, stats.describe_ms);
  EXPECT_GT(repeatability, 0.5);
  EXPECT_LT(errors[errors.size() / 2], 0.5);
  EXPECT_GT(matched, 100);
  EXPECT_GT(precision, 0.9);
}

INSTANTIATE_TEST_SUITE_P(Kinds, FeatureKindTest, ::testing::Values("harris_surf16", "orb"));

TEST(HarrisSurf16Test, DescriptorIgnoresContrastAndBrightness) {
  const ViewPair& v = Views();
  const HarrisSurf16Extractor extractor(HarrisSurf16Options{});
  const std::vector<Keypoint> keypoints = extractor.Detect(v.first);
  cv::Mat dimmer;
  v.first.convertTo(dimmer, CV_8U, 0.5, 20);  // half the contrast, brighter black level
  const cv::Mat a = extractor.Describe(v.first, keypoints);
  const cv::Mat b = extractor.Describe(dimmer, keypoints);
  std::vector<float> distances;
  for (int i = 0; i < a.rows; ++i) distances.push_back(DescriptorDistance(a, i, b, i));
  std::sort(distances.begin(), distances.end());
  EXPECT_LT(distances[distances.size() / 2], 0.05f);  // unit vectors: 0 same, up to 2 opposite
  EXPECT_NEAR(cv::norm(a.row(0)), 1.0, 1e-5);
}

TEST(FeatureSettingsTest, SettingsRoundTripAndUnknownsAreRefused) {
  const FeatureSettings settings = DefaultFeatureSettings("harris_surf16");
  EXPECT_EQ(settings.descriptor_dim, 16);
  EXPECT_EQ(CreateFeatureExtractor(settings)->settings().params, settings.params);
  FeatureSettings unknown = settings;
  unknown.params.emplace_back("sharpness", 3.0);
  EXPECT_THAT(
      [&] { CreateFeatureExtractor(unknown); },
      ::testing::ThrowsMessage<InputError>("unknown harris_surf16 feature parameter 'sharpness'"));
  FeatureSettings kind;
  kind.kind = "sift";
  EXPECT_THROW(CreateFeatureExtractor(kind), InputError);
  EXPECT_EQ(DefaultFeatureSettings("orb").descriptor_type, DescriptorType::kBinary);
}

}  // namespace
}  // namespace visloc
