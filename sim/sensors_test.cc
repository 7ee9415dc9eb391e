#include "sim/sensors.h"

#include <gtest/gtest.h>

#include "sim/sequences.h"

namespace visloc::sim {
namespace {

ImuNoise NoiseFree() {
  ImuNoise noise;
  noise.gyro_noise_density = noise.gyro_bias_sigma = noise.gyro_random_walk = 0;
  noise.accel_noise_density = noise.accel_bias_sigma = noise.accel_random_walk = 0;
  return noise;
}

TEST(ImuTest, NoiseFreeImuIntegratesToTheTrueMotion) {
  const SequenceSpec spec = MakeSequenceSpec("map_square", 1);
  const std::vector<ImuSample> imu = SynthesizeImu(spec.path, 0, NoiseFree(), 1);
  ASSERT_GT(imu.size(), 1000u);
  // Integrate the gyro: the attitude must follow the true attitude over the whole loop.
  Eigen::Quaterniond world_from_body = spec.path.WorldFromBody(0).rotation;
  for (size_t k = 0; k + 1 < imu.size(); ++k) {
    const double dt = (imu[k + 1].timestamp_ns - imu[k].timestamp_ns) * 1e-9;
    const Eigen::Vector3d omega = 0.5 * (imu[k].gyro_radps + imu[k + 1].gyro_radps);
    world_from_body = world_from_body *
                      Eigen::Quaterniond(Eigen::AngleAxisd(omega.norm() * dt, omega.normalized()));
  }
  const Eigen::Quaterniond truth =
      spec.path.WorldFromBody(NsToSeconds(imu.back().timestamp_ns)).rotation;
  EXPECT_LT(RotationAngleDeg(truth.conjugate() * world_from_body), 0.5);
  // The accelerometer reads +g along body z, on average, and no sample has a spike: the
  // gait's start, stops and turns are smooth.
  double sum_z = 0, worst = 0;
  for (const ImuSample& sample : imu) {
    sum_z += sample.accel_mps2.z();
    worst = std::max(worst, (sample.accel_mps2 - Eigen::Vector3d(0, 0, 9.81)).norm());
  }
  EXPECT_NEAR(sum_z / imu.size(), 9.81, 0.02);
  EXPECT_LT(worst, 3.0);
}

TEST(ImuTest, NoisyImuHasTheConfiguredNoiseLevel) {
  const SequenceSpec spec = MakeSequenceSpec("straight", 1);
  const auto clean = SynthesizeImu(spec.path, 0, NoiseFree(), 1);
  ImuNoise noise;
  noise.gyro_bias_sigma = noise.gyro_random_walk = 0;
  const auto noisy = SynthesizeImu(spec.path, 0, noise, 1);
  double sum_sq = 0;
  for (size_t k = 0; k < clean.size(); ++k)
    sum_sq += (noisy[k].gyro_radps - clean[k].gyro_radps).squaredNorm();
  const double sigma = std::sqrt(sum_sq / (3.0 * clean.size()));
  EXPECT_NEAR(sigma, noise.gyro_noise_density * std::sqrt(noise.rate_hz), 0.2 * sigma);
}

TEST(OdometryTest, DriftsLikeAWalkingPlannerAndMissesTheKidnapping) {
  const StereoRig rig = MakeRig(RigOptions{});
  const SequenceSpec square = MakeSequenceSpec("map_square", 1);
  std::vector<double> times;
  for (double t = 0; t <= square.path.duration_s(); t += 1 / 15.0) times.push_back(t);
  const Trajectory odom =
      SynthesizeOdometry(square.path, rig.left.body_from_cam, times, 0, OdometryDrift{}, 1);
  // The true loop closes; the odometry's does not: a few cm per metre, a degree or two per turn.
  const Rigid3d loop = odom.front().pose.Inverse() * odom.back().pose;
  EXPECT_GT(loop.translation.norm(), 0.05);
  EXPECT_LT(loop.translation.norm(), 0.6);
  EXPECT_GT(RotationAngleDeg(loop.rotation), 4.0);
  EXPECT_LT(RotationAngleDeg(loop.rotation), 16.0);

  const SequenceSpec kidnap = MakeSequenceSpec("kidnap", 1);
  const auto [start, end] = kidnap.path.CarriedIntervals().front();
  const Trajectory during =
      SynthesizeOdometry(kidnap.path, rig.left.body_from_cam, {start, end}, 0, OdometryDrift{}, 1);
  EXPECT_LT((during[1].pose.translation - during[0].pose.translation).norm(), 1e-9);
}

}  // namespace
}  // namespace visloc::sim
