// Session-level behaviour that needs no rendered images: input validation and the statuses of
// frames that cannot be localized. Localization accuracy on rendered sequences is tested end to
// end in tests/localization_e2e_test.cc.

#include "core/localization/localizer.h"

#include <gtest/gtest.h>

#include "core/map/synthetic_map.h"
#include "core/util/check.h"

namespace visloc {
namespace {

std::shared_ptr<const LocalizationMap> SmallHarrisMap() {
  SyntheticMapOptions options;
  options.keyframes = 20;
  options.points = 1000;
  Map map = MakeSyntheticMap(options);
  map.features = DefaultFeatureSettings("harris_surf16");
  return std::make_shared<const LocalizationMap>(std::move(map));
}

FrameInput Frame(int64_t timestamp_ns, cv::Mat image) {
  FrameInput input;
  input.timestamp_ns = timestamp_ns;
  input.image = std::move(image);
  return input;
}

TEST(LocalizerTest, RejectsImagesThatDoNotFitTheSessionAndGoesOn) {
  const auto map = SmallHarrisMap();
  Localizer localizer(map, map->map().camera, LocalizerOptions{});
  try {
    localizer.Process(Frame(1, cv::Mat(100, 100, CV_8UC1, cv::Scalar(0))));
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "the image is 100x100 but the session camera is 320x240");
  }
  EXPECT_THROW(localizer.Process(Frame(1, cv::Mat(240, 320, CV_8UC3))), InputError);
  EXPECT_THROW(localizer.Process(Frame(1, cv::Mat())), InputError);
  // The session is still usable, and time must increase.
  const LocalizationResult first =
      localizer.Process(Frame(10, cv::Mat(240, 320, CV_8UC1, cv::Scalar(0))));
  EXPECT_EQ(first.status, TrackingStatus::kInitializing);
  EXPECT_THROW(localizer.Process(Frame(10, cv::Mat(240, 320, CV_8UC1, cv::Scalar(0)))), InputError);
}

TEST(LocalizerTest, ACoveredCameraGetsNoPose) {
  const auto map = SmallHarrisMap();
  Localizer localizer(map, map->map().camera, LocalizerOptions{});
  for (int i = 1; i <= 3; ++i) {
    const LocalizationResult r =
        localizer.Process(Frame(i * 66'000'000LL, cv::Mat(240, 320, CV_8UC1, cv::Scalar(3))));
    EXPECT_EQ(r.status, TrackingStatus::kInitializing);
    EXPECT_FALSE(r.has_pose);
    EXPECT_EQ(r.source, PoseSource::kNone);
    EXPECT_EQ(r.stats.features, 0);
    EXPECT_EQ(r.relocalization.kind, RelocalizationReport::Kind::kGlobal);
    EXPECT_FALSE(r.relocalization.found);
    EXPECT_GT(r.stats.times.total_ms, 0.0);
  }
}

// A robot that is not found tries the tracking features first (as the Relocalize RPC does),
// then the relocalization features. Once neither found it, its frames go straight to the
// relocalization features until it is found: the tracking features would be unused work (a
// quarter of a lost frame at 752x480) and their pass would fail again.
TEST(LocalizerTest, ARobotThatStaysLostStopsTryingTheTrackingFeatures) {
  const auto map = SmallHarrisMap();
  cv::Mat texture(240, 320, CV_8UC1);
  cv::randu(texture, 0, 256);
  Localizer localizer(map, map->map().camera, LocalizerOptions{});
  const LocalizationResult first = localizer.Process(Frame(66'000'000LL, texture));
  EXPECT_EQ(first.status, TrackingStatus::kInitializing);
  EXPECT_GT(first.stats.features, 100);
  EXPECT_EQ(first.relocalization.feature_passes, 2);
  EXPECT_FALSE(first.relocalization.found);
  const LocalizationResult lost = localizer.Process(Frame(132'000'000LL, texture));
  EXPECT_EQ(lost.status, TrackingStatus::kInitializing);
  EXPECT_EQ(lost.stats.times.detect_ms, 0.0);
  EXPECT_EQ(lost.stats.times.describe_ms, 0.0);
  EXPECT_EQ(lost.stats.features, 0);
  EXPECT_EQ(lost.relocalization.feature_passes, 1);
  EXPECT_GT(lost.stats.times.relocalize_ms, 0.0);
  // A hint is a prior: tracking is tried first, with its own features.
  FrameInput hinted = Frame(198'000'000LL, texture);
  hinted.map_from_cam_hint = map->map().keyframes.front().map_from_cam;
  const LocalizationResult tried = localizer.Process(hinted);
  EXPECT_GT(tried.stats.times.detect_ms, 0.0);
  EXPECT_GT(tried.stats.features, 100);
  EXPECT_EQ(tried.relocalization.feature_passes, 1);  // Still lost: the full features only.
}

TEST(LocalizerTest, OptionsAreChecked) {
  const auto map = SmallHarrisMap();
  LocalizerOptions options;
  options.min_tracking_inliers = 5;  // Below the limited threshold.
  EXPECT_THROW(Localizer(map, map->map().camera, options), CheckError);
  options = LocalizerOptions{};
  options.resample_ratio = 0.9;  // Would resample a camera of the map's own focal length.
  EXPECT_THROW(Localizer(map, map->map().camera, options), CheckError);
  options = LocalizerOptions{};
  options.motion.plane_sigma_m = 0.02;  // The synthetic keyframes lie on a circle: a plane.
  EXPECT_NO_THROW(Localizer(map, map->map().camera, options));
}

TEST(LocalizerTest, KeyframePlaneOfARobotWalkingACircle) {
  const auto map = SmallHarrisMap();
  const auto plane = FitKeyframePlane(*map);
  ASSERT_TRUE(plane.has_value());
  // Keyframes lie in z = 0 with cameras looking sideways, y down = -z: the normal is +z.
  EXPECT_TRUE(plane->first.isApprox(Eigen::Vector3d::UnitZ(), 1e-9));
  EXPECT_NEAR(plane->second, 0.0, 1e-9);
}

}  // namespace
}  // namespace visloc
