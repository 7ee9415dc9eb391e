#include "mapping/session_registration.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>

#include "core/util/check.h"
#include "core/util/random.h"

namespace visloc::mapping {
namespace {

// A session's images as its own mapping placed them (a walk in a frame of its own), and as
// localizing them in the map did: `map_from_session` places them, up to noise (5 mm, 0.1 deg).
struct PlacedTwice {
  Trajectory session_from_cam;
  Trajectory map_from_cam;
};

PlacedTwice Walk(const Rigid3d& map_from_session, int frames) {
  PlacedTwice walk;
  Rng rng(5);
  for (int i = 0; i < frames; ++i) {
    const double angle = 2 * M_PI * i / frames;  // A 2 m circle, looking ahead.
    const Rigid3d session_from_cam(
        Eigen::Quaterniond(Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitY())),
        Eigen::Vector3d(std::cos(angle), 0.0, std::sin(angle)));
    const Eigen::Vector3d axis(rng.Uniform(-1, 1), rng.Uniform(-1, 1), rng.Uniform(-1, 1));
    const Rigid3d noise(
        Eigen::Quaterniond(Eigen::AngleAxisd(0.1 * M_PI / 180, axis.normalized())),
        0.005 * Eigen::Vector3d(rng.Uniform(-1, 1), rng.Uniform(-1, 1), rng.Uniform(-1, 1)));
    const int64_t t_ns = 1'000'000'000 + i * 66'666'667LL;
    walk.session_from_cam.push_back({t_ns, session_from_cam});
    walk.map_from_cam.push_back({t_ns, noise * map_from_session * session_from_cam});
  }
  return walk;
}

const Rigid3d kMapFromSession(
    Eigen::Quaterniond(Eigen::AngleAxisd(1.2, Eigen::Vector3d(0.1, 0.2, 1).normalized())),
    Eigen::Vector3d(4.0, -2.0, 0.3));

TEST(SessionRegistrationTest, TheImagesThatAgreePlaceTheSessionAndLookAlikesAreLeftOut) {
  PlacedTwice walk = Walk(kMapFromSession, 40);
  // Five images localized at a look-alike place 2 m away (a wrong relocalization, then tracked
  // there), five not at all, and one the session's mapping did not place.
  for (int i = 0; i < 5; ++i)
    walk.map_from_cam[i].pose.translation += Eigen::Vector3d(2.0, 0.0, 0.0);
  walk.map_from_cam.erase(walk.map_from_cam.begin() + 10, walk.map_from_cam.begin() + 15);
  walk.map_from_cam.push_back({walk.map_from_cam.back().timestamp_ns + 1, Rigid3d()});
  SessionRegistrationStats stats;
  const Rigid3d fit = FitMapFromSession(walk.session_from_cam, walk.map_from_cam,
                                        SessionRegistrationOptions{}, &stats);
  EXPECT_TRUE(ApproxEqual(fit, kMapFromSession, 0.003, 0.1));
  EXPECT_EQ(stats.paired_frames, 35);
  EXPECT_EQ(stats.agreeing_frames, 30);
  EXPECT_LT(stats.position_rmse_m, 0.01);
}

TEST(SessionRegistrationTest, ACameraThatStoodStillIsPlacedToo) {
  // One pose, seen in many images (a still camera maps one keyframe): orientation and position
  // both come from it.
  PlacedTwice still = Walk(kMapFromSession, 40);
  for (size_t i = 0; i < still.session_from_cam.size(); ++i) {
    still.session_from_cam[i].pose = still.session_from_cam[0].pose;
    still.map_from_cam[i].pose = kMapFromSession * still.session_from_cam[0].pose;
  }
  SessionRegistrationStats stats;
  const Rigid3d fit = FitMapFromSession(still.session_from_cam, still.map_from_cam,
                                        SessionRegistrationOptions{}, &stats);
  EXPECT_TRUE(ApproxEqual(fit, kMapFromSession, 1e-6, 1e-4));
  EXPECT_EQ(stats.agreeing_frames, 40);
}

TEST(SessionRegistrationTest, TooFewAgreeingImagesAreRefusedWithTheEvidence) {
  const PlacedTwice walk = Walk(kMapFromSession, 40);
  SessionRegistrationStats stats;
  try {
    FitMapFromSession(walk.session_from_cam, {walk.map_from_cam[3], walk.map_from_cam[20]},
                      SessionRegistrationOptions{}, &stats);
    FAIL() << "a session placed by two images";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("2 of the 2 images that localized in the map"));
  }
  EXPECT_THROW(FitMapFromSession(walk.session_from_cam, {}, SessionRegistrationOptions{}, &stats),
               InputError);
}

}  // namespace
}  // namespace visloc::mapping
