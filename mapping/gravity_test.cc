#include "mapping/gravity.h"

#include <cmath>

#include <gtest/gtest.h>

#include "core/util/random.h"

namespace visloc::mapping {
namespace {

constexpr double kG = 9.81;

double AngleDeg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b)) * 180.0 / M_PI;
}

// A world with z up, and a map frame whose first camera is pitched and rolled: the truth's up
// in the map frame is R_map_world z.
struct Scene {
  Rigid3d world_from_map;
  Eigen::Vector3d UpInMap() const {
    return world_from_map.rotation.inverse() * Eigen::Vector3d::UnitZ();
  }
};

Scene TiltedScene() {
  // The camera looks along world x (camera z = world x, camera y = -world z), then pitched down
  // 20 deg and rolled 12 deg.
  Eigen::Matrix3d level;
  level << 0, 0, 1,  //
      -1, 0, 0,      //
      0, -1, 0;
  const Eigen::Quaterniond tilt = RotationFromRollPitchYaw(0.21, 0.35, 0.0);
  return {Rigid3d(tilt * Eigen::Quaterniond(level), Eigen::Vector3d(0, 0, 1.4))};
}

// The body (= camera here) walks a circle of radius 1 m in 20 s, turning with it, with a
// vertical bob, and (`glance_rad`) a head turning that far and back every 2 s; IMU samples at
// 200 Hz from the exact motion, with a bias and white noise; poses at `fps`.
void CircleWalk(const Scene& scene, const Eigen::Vector3d& bias_body, bool still,
                Trajectory* map_from_cam, std::vector<ImuReading>* samples, double fps = 15,
                double glance_rad = 0) {
  const Rigid3d map_from_world = scene.world_from_map.Inverse();
  const double radius = still ? 0.0 : 1.0, period_s = 20.0, bob = still ? 0.0 : 0.01;
  const double turn_rate = still ? 0.0 : 2 * M_PI / period_s;
  const auto yaw_at = [&](double t) {
    return turn_rate * t + glance_rad * 0.5 * (1 - std::cos(M_PI * t));
  };
  const auto world_from_cam = [&](double t) {
    const double a = 2 * M_PI * t / period_s;
    const Eigen::Vector3d position(radius * std::sin(a), radius * (1 - std::cos(a)),
                                   1.4 + bob * std::sin(2 * M_PI * 1.6 * t));
    const Eigen::Quaterniond yaw(Eigen::AngleAxisd(yaw_at(t), Eigen::Vector3d::UnitZ()));
    return Rigid3d(yaw * scene.world_from_map.rotation, position);
  };
  Rng rng(3);
  for (int i = 0; i <= 20 * 200; ++i) {
    const double t = i / 200.0, h = 1e-3;
    const Rigid3d pose = world_from_cam(t);
    const Eigen::Vector3d accel_world = (world_from_cam(t + h).translation - 2 * pose.translation +
                                         world_from_cam(t - h).translation) /
                                        (h * h);
    ImuReading sample;
    sample.timestamp_ns = SecondsToNs(t);
    sample.specific_force_mps2 =
        pose.rotation.inverse() * (accel_world + Eigen::Vector3d(0, 0, kG)) + bias_body +
        Eigen::Vector3d(rng.Normal(0, 0.03), rng.Normal(0, 0.03), rng.Normal(0, 0.03));
    const double yaw_rate = (yaw_at(t + h) - yaw_at(t - h)) / (2 * h);
    sample.angular_rate_radps = pose.rotation.inverse() * Eigen::Vector3d(0, 0, yaw_rate);
    samples->push_back(sample);
  }
  for (int f = 0; f <= 20 * fps; ++f) {
    const double t = f / fps;
    map_from_cam->push_back({SecondsToNs(t), map_from_world * world_from_cam(t)});
  }
}

TEST(GravityTest, AWalkThatTurnsTellsTheAccelerometersBiasFromGravity) {
  const Scene scene = TiltedScene();
  Trajectory poses;
  std::vector<ImuReading> samples;
  const Eigen::Vector3d bias(0.25, -0.3, 0.1);  // Half a metre a second squared: 3 deg if ignored.
  CircleWalk(scene, bias, /*still=*/false, &poses, &samples);
  const GravityResult result = GravityFromImu(poses, samples, Rigid3d());
  ASSERT_TRUE(result.gravity) << result.why_not;
  EXPECT_EQ(result.gravity->source, MapGravity::Source::kImu);
  EXPECT_LT(AngleDeg(result.gravity->up_in_map, scene.UpInMap()), 0.1);
  EXPECT_LE(result.gravity->sigma_deg, 0.2);
}

// Poses at 5 fps while the head glances 110 deg and back every 2 s: 17 deg between frames, which
// the gyro follows and a slerp between the poses would not.
TEST(GravityTest, AHeadTurningFastBetweenFramesIsFollowedByTheGyro) {
  const Scene scene = TiltedScene();
  Trajectory poses;
  std::vector<ImuReading> samples;
  CircleWalk(scene, Eigen::Vector3d(0.05, -0.05, 0.02), /*still=*/false, &poses, &samples,
             /*fps=*/5, /*glance_rad=*/110 * M_PI / 180);
  const GravityResult result = GravityFromImu(poses, samples, Rigid3d());
  ASSERT_TRUE(result.gravity) << result.why_not;
  EXPECT_LT(AngleDeg(result.gravity->up_in_map, scene.UpInMap()), 0.1);
}

TEST(GravityTest, AStillRecordingCannotTellTheBiasAndItsSigmaSaysSo) {
  const Scene scene = TiltedScene();
  Trajectory poses;
  std::vector<ImuReading> samples;
  const Eigen::Vector3d bias(0.45, 0.0, 0.0);  // The camera's x, across up: 2.6 deg.
  CircleWalk(scene, bias, /*still=*/true, &poses, &samples);
  const GravityResult result = GravityFromImu(poses, samples, Rigid3d());
  ASSERT_TRUE(result.gravity) << result.why_not;
  const double error_deg = AngleDeg(result.gravity->up_in_map, scene.UpInMap());
  EXPECT_GT(error_deg, 1.5);  // The bias is in it ...
  EXPECT_GT(result.gravity->sigma_deg, error_deg / 3);  // ... and the sigma covers it.
}

TEST(GravityTest, AnAccelerometerInTheWrongUnitsIsRefusedByItsMagnitude) {
  const Scene scene = TiltedScene();
  Trajectory poses;
  std::vector<ImuReading> samples;
  CircleWalk(scene, Eigen::Vector3d::Zero(), /*still=*/false, &poses, &samples);
  for (ImuReading& s : samples) s.specific_force_mps2 /= kG;  // In g.
  const GravityResult result = GravityFromImu(poses, samples, Rigid3d());
  EXPECT_FALSE(result.gravity);
  EXPECT_NE(result.why_not.find("gravity of 1.00 m/s^2, not 9.81"), std::string::npos)
      << result.why_not;
  EXPECT_EQ(GravityFromImu(poses, {}, Rigid3d()).why_not, "the recording has no accelerometer");
  // Samples from another clock: none overlaps the poses.
  for (ImuReading& s : samples) s.timestamp_ns += SecondsToNs(100);
  EXPECT_NE(GravityFromImu(poses, samples, Rigid3d()).why_not.find("overlaps the camera poses"),
            std::string::npos);
}

// A room's map: a floor 1.4 m below the cameras, two walls, keyframes along a walk in the map
// frame of TiltedScene.
Map RoomMap(const Scene& scene, bool with_floor, bool planar_walk) {
  Map map;
  const Rigid3d map_from_world = scene.world_from_map.Inverse();
  Rng rng(5);
  const auto add = [&](const Eigen::Vector3d& world) {
    MapPoint point;
    point.position_in_map = map_from_world * world;
    map.points.push_back(point);
  };
  for (int i = 0; i < 600 && with_floor; ++i) {
    add({rng.Uniform(-1, 5), rng.Uniform(-3, 3), rng.Normal(0, 0.005)});
  }
  for (int i = 0; i < 400; ++i) {
    add({5.0 + rng.Normal(0, 0.005), rng.Uniform(-3, 3), rng.Uniform(0, 2.5)});
  }
  for (int i = 0; i < 300; ++i) add({rng.Uniform(-1, 5), 3.0, rng.Uniform(0, 2.5)});
  for (int k = 0; k < 20; ++k) {
    const double a = 2 * M_PI * k / 20;
    const Eigen::Vector3d centre(std::sin(a), 1 - std::cos(a),
                                 1.4 + (planar_walk ? 0.0 : 0.5 * std::sin(3 * a)));
    const Eigen::Quaterniond yaw(Eigen::AngleAxisd(0.3 * std::sin(a), Eigen::Vector3d::UnitZ()));
    map.keyframes.push_back(
        {k, map_from_world * Rigid3d(yaw * scene.world_from_map.rotation, centre)});
  }
  return map;
}

TEST(GravityTest, TheFloorBeneathTheKeyframesGivesUpThoughTheFirstCameraWasTilted) {
  const Scene scene = TiltedScene();
  const GravityResult result = GravityFromFloor(RoomMap(scene, true, true));
  ASSERT_TRUE(result.gravity) << result.why_not;
  EXPECT_EQ(result.gravity->source, MapGravity::Source::kFloor);
  EXPECT_LT(AngleDeg(result.gravity->up_in_map, scene.UpInMap()), 0.2);
  EXPECT_GE(result.gravity->sigma_deg, 0.5);  // A floor is level only as well as it was laid.
}

TEST(GravityTest, WithoutAFloorTheKeyframesMotionPlaneGivesUpElseItSaysWhy) {
  const Scene scene = TiltedScene();
  const GravityResult plane = GravityFromFloor(RoomMap(scene, false, true));
  ASSERT_TRUE(plane.gravity) << plane.why_not;
  EXPECT_EQ(plane.gravity->source, MapGravity::Source::kMotionPlane);
  EXPECT_LT(AngleDeg(plane.gravity->up_in_map, scene.UpInMap()), 0.5);
  const GravityResult none = GravityFromFloor(RoomMap(scene, false, false));
  EXPECT_FALSE(none.gravity);
  EXPECT_NE(none.why_not.find("no floor beneath the keyframes, and the keyframes did not keep to"),
            std::string::npos)
      << none.why_not;
}

// EuRoC MH_01's start: the cameras barely move, and the only floor they see is a patch under
// them, 0.8 x 1.0 m, tilted 4 deg from the hall's vertical. Taken as up, it put the map 3.8 deg
// off level while its sigma said 1.0.
TEST(GravityTest, ASmallPatchOfFloorIsNotTakenForUpAndItsSigmaCoversItsTilt) {
  const Scene scene = TiltedScene();
  const Rigid3d map_from_world = scene.world_from_map.Inverse();
  const Eigen::Quaterniond patch_tilt(
      Eigen::AngleAxisd(4.0 * M_PI / 180.0, Eigen::Vector3d::UnitX()));
  Map map;
  Rng rng(9);
  for (int i = 0; i < 800; ++i) {
    const Eigen::Vector3d on_patch(rng.Uniform(0.2, 1.0), rng.Uniform(-0.5, 0.5), 0.0);
    MapPoint point;
    point.position_in_map = map_from_world * (patch_tilt * on_patch + Eigen::Vector3d(0, 0, 0.6));
    map.points.push_back(point);
  }
  for (int k = 0; k < 10; ++k) {
    const Eigen::Vector3d centre(0.02 * k, 0.0, 1.2);
    map.keyframes.push_back({k, map_from_world * Rigid3d(scene.world_from_map.rotation, centre)});
  }
  const GravityResult taken = GravityFromFloor(map);
  EXPECT_FALSE(taken.gravity);
  EXPECT_NE(taken.why_not.find("the floor seen spans only 0.8 x 1.0 m: level within 3."),
            std::string::npos)
      << taken.why_not;
  GravityOptions to_draw;
  to_draw.max_floor_sigma_deg = 10.0;
  const GravityResult drawn = GravityFromFloor(map, to_draw);
  ASSERT_TRUE(drawn.gravity) << drawn.why_not;
  const double error_deg = AngleDeg(drawn.gravity->up_in_map, scene.UpInMap());
  EXPECT_NEAR(error_deg, 4.0, 0.3);
  EXPECT_GT(drawn.gravity->sigma_deg, error_deg / 1.5);
}

// A still recording leaves the accelerometer's bias in both tilts; the room's floor, seen
// wide, tells them. A walk that turns keeps the accelerometer's own, which the floor barely moves.
TEST(GravityTest, TheFloorTellsTheTiltsTheAccelerometersBiasLeftLoose) {
  const Scene scene = TiltedScene();
  const GravityResult floor = GravityFromFloor(RoomMap(scene, true, true));
  ASSERT_TRUE(floor.gravity) << floor.why_not;
  Trajectory poses;
  std::vector<ImuReading> samples;
  CircleWalk(scene, Eigen::Vector3d(0.45, 0.0, 0.0), /*still=*/true, &poses, &samples);
  const GravityResult still = GravityFromImu(poses, samples, Rigid3d());
  ASSERT_TRUE(still.gravity) << still.why_not;
  const double still_error_deg = AngleDeg(still.gravity->up_in_map, scene.UpInMap());
  const GravityResult combined = CombineImuAndFloor(still, floor);
  ASSERT_TRUE(combined.gravity) << combined.why_not;
  EXPECT_EQ(combined.gravity->source, MapGravity::Source::kImuAndFloor);
  const double combined_error_deg = AngleDeg(combined.gravity->up_in_map, scene.UpInMap());
  EXPECT_LT(combined_error_deg, 0.5 * still_error_deg);
  EXPECT_LT(combined.gravity->sigma_deg,
            std::min(still.gravity->sigma_deg, floor.gravity->sigma_deg));
  EXPECT_GT(combined.gravity->sigma_deg, combined_error_deg / 3);

  poses.clear();
  samples.clear();
  CircleWalk(scene, Eigen::Vector3d(0.25, -0.3, 0.1), /*still=*/false, &poses, &samples);
  const GravityResult turning = GravityFromImu(poses, samples, Rigid3d());
  ASSERT_TRUE(turning.gravity) << turning.why_not;
  const GravityResult kept = CombineImuAndFloor(turning, floor);
  ASSERT_TRUE(kept.gravity) << kept.why_not;
  EXPECT_LT(AngleDeg(kept.gravity->up_in_map, turning.gravity->up_in_map), 0.02);
  EXPECT_LT(AngleDeg(kept.gravity->up_in_map, scene.UpInMap()), 0.1);
}

// A ramp is not level: a floor 8 deg off a well-known accelerometer's up is not combined.
TEST(GravityTest, AFloorThatDisagreesWithTheAccelerometerIsNotCombined) {
  const Scene scene = TiltedScene();
  GravityResult floor = GravityFromFloor(RoomMap(scene, true, true));
  ASSERT_TRUE(floor.gravity) << floor.why_not;
  const Eigen::Vector3d axis = floor.gravity->up_in_map.unitOrthogonal();
  floor.gravity->up_in_map = Eigen::AngleAxisd(8.0 * M_PI / 180.0, axis) * floor.gravity->up_in_map;
  Trajectory poses;
  std::vector<ImuReading> samples;
  CircleWalk(scene, Eigen::Vector3d(0.05, -0.05, 0.02), /*still=*/false, &poses, &samples);
  const GravityResult imu = GravityFromImu(poses, samples, Rigid3d());
  ASSERT_TRUE(imu.gravity) << imu.why_not;
  const GravityResult combined = CombineImuAndFloor(imu, floor);
  EXPECT_FALSE(combined.gravity);
  EXPECT_NE(combined.why_not.find("the floor and the accelerometer disagree by 8.0"),
            std::string::npos)
      << combined.why_not;
}

TEST(GravityTest, ALevelBodyIsUpThroughItsCamerasPlacement) {
  const Scene scene = TiltedScene();
  Map map;
  map.keyframes.push_back({0, Rigid3d()});
  // The body is the world's orientation at the camera: body_from_cam = world_from_map's rotation.
  const MapGravity gravity =
      GravityFromLevelBody(map, Rigid3d(scene.world_from_map.rotation, Eigen::Vector3d::Zero()));
  EXPECT_EQ(gravity.source, MapGravity::Source::kLevelRig);
  EXPECT_LT(AngleDeg(gravity.up_in_map, scene.UpInMap()), 1e-9);
  EXPECT_EQ(gravity.sigma_deg, GravityOptions{}.level_body_sigma_deg);
}

}  // namespace
}  // namespace visloc::mapping
