// Session-level behaviour that needs no rendered images: input validation and the statuses of
// frames that cannot be localized. Localization accuracy on rendered sequences is tested end to
// end in tests/localization_e2e_test.cc.

#include "core/localization/localizer.h"

#include <chrono>
#include <thread>

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

// A rig of the map's camera and a rear camera 0.1 m behind it looking back.
CameraRig FrontBackRig(const Camera& camera) {
  CameraRig rig;
  rig.cameras = {camera, camera};
  rig.body_from_cam = {
      Rigid3d(), Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitY())),
                         Eigen::Vector3d(0, 0, -0.1))};
  return rig;
}

FrameInput RigFrame(int64_t timestamp_ns, const cv::Mat& front, const cv::Mat& rear,
                    int64_t rear_offset_ns = 0) {
  FrameInput input = Frame(timestamp_ns, front);
  input.rig_images.push_back({timestamp_ns + rear_offset_ns, rear});
  return input;
}

TEST(LocalizerTest, ARigsFrameIsCheckedCameraByCameraAndTheSessionGoesOn) {
  const auto map = SmallHarrisMap();
  Localizer localizer(map, FrontBackRig(map->map().camera), LocalizerOptions{});
  const cv::Mat dark(240, 320, CV_8UC1, cv::Scalar(3));
  const auto refused = [&](const FrameInput& input) {
    try {
      localizer.Process(input);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_EQ(refused(Frame(1, dark)),
            "the session's rig has 2 cameras but the frame carries 1 images");
  EXPECT_EQ(refused(RigFrame(1, dark, cv::Mat(100, 100, CV_8UC1, cv::Scalar(0)))),
            "camera 1's image is 100x100 of type 0 but the camera is 320x240 8-bit grey");
  // Taken 8 ms apart: not the same moment (the default tolerance is 5 ms).
  EXPECT_EQ(refused(RigFrame(10'000'000, dark, dark, 8'000'000)),
            "camera 1's image was taken 8 ms from the reference camera's (at most 5 ms)");
  // A camera that gave no image this time is no error; all cameras blind: no pose.
  const LocalizationResult none = localizer.Process(RigFrame(20'000'000, dark, cv::Mat()));
  EXPECT_EQ(none.status, TrackingStatus::kInitializing);
  const LocalizationResult blind = localizer.Process(RigFrame(86'000'000, dark, dark, 2'000'000));
  EXPECT_EQ(blind.status, TrackingStatus::kInitializing);
  EXPECT_FALSE(blind.has_pose);
  EXPECT_EQ(blind.relocalization.kind, RelocalizationReport::Kind::kGlobal);
}

// Whether a rig session on two threads, given 8 frames 10 ms apart, had its helper wake ahead
// of an expected frame (waiting up to 10 s for the wake after the last frame).
bool HelperWokeAhead(bool wake_ahead) {
  const auto map = SmallHarrisMap();
  LocalizerOptions options;
  options.rig_threads = 2;
  options.rig_wake_ahead = wake_ahead;
  Localizer localizer(map, FrontBackRig(map->map().camera), options);
  const cv::Mat dark(240, 320, CV_8UC1, cv::Scalar(3));
  for (int i = 0; i < 8; ++i) {
    localizer.Process(RigFrame((i + 1) * 10'000'000, dark, dark));
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  const auto deadline =
      std::chrono::steady_clock::now() + std::chrono::seconds(wake_ahead ? 10 : 1);
  while (std::chrono::steady_clock::now() < deadline) {
    if (localizer.rig_expectation_stats().wakes > 0) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return false;
}

TEST(LocalizerTest, ARigsHelperWakesAheadOfFramesThatKeepARhythmUnlessToldNot) {
  EXPECT_TRUE(HelperWokeAhead(true));
  EXPECT_FALSE(HelperWokeAhead(false));
}

TEST(LocalizerTest, ARigIsOneToEightCamerasEachPlaced) {
  const auto map = SmallHarrisMap();
  CameraRig rig = FrontBackRig(map->map().camera);
  rig.body_from_cam.pop_back();
  EXPECT_THROW(Localizer(map, rig, LocalizerOptions{}), InputError);
  rig.cameras.assign(9, map->map().camera);
  rig.body_from_cam.assign(9, Rigid3d());
  EXPECT_THROW(Localizer(map, rig, LocalizerOptions{}), InputError);
  rig.cameras.clear();
  rig.body_from_cam.clear();
  EXPECT_THROW(Localizer(map, rig, LocalizerOptions{}), InputError);
  // Camera c's placement on the rig, from both on the body.
  rig = FrontBackRig(map->map().camera);
  const Rigid3d body_from_front(RotationFromRollPitchYaw(0.1, 0.2, 0.3), Eigen::Vector3d(1, 2, 3));
  rig.body_from_cam = {body_from_front,
                       body_from_front * FrontBackRig(map->map().camera).body_from_cam[1]};
  EXPECT_TRUE(ApproxEqual(rig.CamFromReference(1),
                          FrontBackRig(map->map().camera).body_from_cam[1].Inverse(), 1e-12, 1e-9));
  EXPECT_TRUE(ApproxEqual(rig.CamFromReference(0), Rigid3d(), 1e-12, 1e-9));
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
