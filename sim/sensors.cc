#include "sim/sensors.h"

#include <cmath>

#include "core/util/random.h"

namespace visloc::sim {
namespace {

constexpr double kGravity = 9.81;  // m/s^2, world -z.

Eigen::Vector3d LogRotation(const Eigen::Quaterniond& q) {
  const Eigen::AngleAxisd angle_axis(q.normalized());
  return angle_axis.angle() * angle_axis.axis();
}

Eigen::Vector3d RandomVector(Rng& rng, double sigma) {
  return Eigen::Vector3d(rng.Normal(0, sigma), rng.Normal(0, sigma), rng.Normal(0, sigma));
}

}  // namespace

void TrueKinematics(const WalkingPath& path, double time_s, Eigen::Vector3d* omega_body,
                    Eigen::Vector3d* accel_world, double h) {
  const Rigid3d before = path.WorldFromBody(time_s - h);
  const Rigid3d now = path.WorldFromBody(time_s);
  const Rigid3d after = path.WorldFromBody(time_s + h);
  // R(t+h) = R(t-h) exp(omega 2h) for a body-frame rate omega.
  *omega_body = LogRotation(before.rotation.conjugate() * after.rotation) / (2.0 * h);
  *accel_world = (after.translation - 2.0 * now.translation + before.translation) / (h * h);
}

std::vector<ImuSample> SynthesizeImu(const WalkingPath& path, int64_t start_ns,
                                     const ImuNoise& noise, uint64_t seed) {
  Rng rng(seed * 31 + 7);
  const double dt = 1.0 / noise.rate_hz;
  Eigen::Vector3d gyro_bias = RandomVector(rng, noise.gyro_bias_sigma);
  Eigen::Vector3d accel_bias = RandomVector(rng, noise.accel_bias_sigma);
  const double gyro_sigma = noise.gyro_noise_density / std::sqrt(dt);
  const double accel_sigma = noise.accel_noise_density / std::sqrt(dt);
  std::vector<ImuSample> samples;
  const int count = static_cast<int>(std::floor(path.duration_s() * noise.rate_hz)) + 1;
  for (int k = 0; k < count; ++k) {
    const double t = k * dt;
    Eigen::Vector3d omega_body, accel_world;
    TrueKinematics(path, t, &omega_body, &accel_world);
    const Eigen::Quaterniond world_from_body = path.WorldFromBody(t).rotation;
    const Eigen::Vector3d specific_force =
        world_from_body.conjugate() * (accel_world + Eigen::Vector3d(0, 0, kGravity));
    ImuSample sample;
    sample.timestamp_ns = start_ns + static_cast<int64_t>(std::llround(t * 1e9));
    sample.gyro_radps = omega_body + gyro_bias + RandomVector(rng, gyro_sigma);
    sample.accel_mps2 = specific_force + accel_bias + RandomVector(rng, accel_sigma);
    samples.push_back(sample);
    gyro_bias += RandomVector(rng, noise.gyro_random_walk * std::sqrt(dt));
    accel_bias += RandomVector(rng, noise.accel_random_walk * std::sqrt(dt));
  }
  return samples;
}

Trajectory SynthesizeOdometry(const WalkingPath& path, const Rigid3d& body_from_cam,
                              const std::vector<double>& frame_times_s, int64_t start_ns,
                              const OdometryDrift& drift, uint64_t seed) {
  Rng rng(seed * 131 + 3);
  const double stride_error = (rng.Uniform01() < 0.5 ? -1 : 1) * drift.stride_scale_error;
  const double turn_error = (rng.Uniform01() < 0.5 ? -1 : 1) * drift.turn_scale_error;
  const double creep = (rng.Uniform01() < 0.5 ? -1 : 1) * drift.lateral_creep;
  const auto carried = path.CarriedIntervals();
  auto is_carried = [&](double t) {
    for (const auto& [start, end] : carried) {
      if (t >= start && t < end) return true;
    }
    return false;
  };

  // The odometry's planar pose, integrated from planned increments in substeps.
  double x = 0, y = 0, yaw = 0;
  double previous_t = 0.0;      // Previous frame time.
  double previous_sub_t = 0.0;  // Previous substep time.
  PlanarPose previous_plan = path.PlannedAt(0.0);
  Trajectory odom_from_cam;
  constexpr int kSubsteps = 10;
  for (double frame_t : frame_times_s) {
    for (int k = 1; k <= kSubsteps; ++k) {
      const double t = previous_t + (frame_t - previous_t) * k / kSubsteps;
      const PlanarPose plan = path.PlannedAt(t);
      if (!is_carried(0.5 * (t + previous_sub_t))) {
        // The planned increment in the previous heading's frame.
        const double c = std::cos(previous_plan.yaw), s = std::sin(previous_plan.yaw);
        const double dx = plan.x - previous_plan.x, dy = plan.y - previous_plan.y;
        const double forward = c * dx + s * dy, left = -s * dx + c * dy;
        double dyaw = plan.yaw - previous_plan.yaw;
        const double step = std::hypot(forward, left);
        const double odom_forward =
            forward * (1 + stride_error) + rng.Normal(0, drift.slip_sigma_m * std::sqrt(step));
        const double odom_left = left * (1 + stride_error) + creep * step;
        dyaw = dyaw * (1 + turn_error) + rng.Normal(0, drift.slip_sigma_rad * std::sqrt(step));
        x += std::cos(yaw) * odom_forward - std::sin(yaw) * odom_left;
        y += std::sin(yaw) * odom_forward + std::cos(yaw) * odom_left;
        yaw += dyaw;
      }
      previous_plan = plan;
      previous_sub_t = t;
    }
    previous_t = frame_t;
    const Rigid3d odom_from_body(RotationFromRollPitchYaw(0, 0, yaw),
                                 Eigen::Vector3d(x, y, path.gait().camera_height_m));
    odom_from_cam.push_back({start_ns + static_cast<int64_t>(std::llround(frame_t * 1e9)),
                             odom_from_body * body_from_cam});
  }
  return odom_from_cam;
}

}  // namespace visloc::sim
