#pragma once
// Proprioceptive sensors synthesised from a walking path.
//
// IMU: angular rate and specific force of the body frame, from the true motion by central
// differences, plus white noise and a slowly wandering bias (continuous-time densities as in
// EuRoC's ADIS16448 sensor.yaml, discretised at the IMU rate).
//
// Odometry: the pattern generator's idea of the motion. It integrates the *planned* floor
// motion with systematic errors a walking robot has: stride length off by a few percent, turns
// off by a degree or two per 90 degrees, a slow sideways creep, and small random slips. It
// never sees the gait's bob and sway, nor a kidnapping (being carried is not walking). Poses
// are the left camera's in the odometry frame, which starts at the robot's first planned pose.

#include <cstdint>
#include <vector>

#include "core/geometry/trajectory.h"
#include "dataset/dataset.h"
#include "sim/walking_path.h"

namespace visloc::sim {

struct ImuNoise {
  double rate_hz = 200.0;
  double gyro_noise_density = 1.7e-4;   // rad / s / sqrt(Hz)
  double gyro_bias_sigma = 3e-3;        // rad / s, initial bias spread
  double gyro_random_walk = 1.9e-5;     // rad / s^2 / sqrt(Hz)
  double accel_noise_density = 2.0e-3;  // m / s^2 / sqrt(Hz)
  double accel_bias_sigma = 3e-2;       // m / s^2
  double accel_random_walk = 3.0e-3;    // m / s^3 / sqrt(Hz)
};

// Samples from t = 0 to the path's end; timestamps are `start_ns` + t.
std::vector<ImuSample> SynthesizeImu(const WalkingPath& path, int64_t start_ns,
                                     const ImuNoise& noise, uint64_t seed);

struct OdometryDrift {
  double stride_scale_error = 0.03;  // Relative error of walked distance (3 cm per metre).
  double turn_scale_error = 0.025;   // Relative error of turned angle (2.25 deg per 90 deg).
  double lateral_creep = 0.01;       // Sideways metres per metre walked.
  double slip_sigma_m = 0.002;       // Random slip per metre walked.
  double slip_sigma_rad = 0.002;     // Random heading slip per metre walked.
};

// Odometry camera poses at `frame_times_s` (relative to path start), stamped start_ns + t. The
// signs of the systematic errors are drawn from `seed`.
Trajectory SynthesizeOdometry(const WalkingPath& path, const Rigid3d& body_from_cam,
                              const std::vector<double>& frame_times_s, int64_t start_ns,
                              const OdometryDrift& drift, uint64_t seed);

// Body angular velocity (rad/s, body frame) and world acceleration (m/s^2) of the true motion
// at t, by central differences over +-h seconds.
void TrueKinematics(const WalkingPath& path, double time_s, Eigen::Vector3d* omega_body,
                    Eigen::Vector3d* accel_world, double h = 1e-3);

}  // namespace visloc::sim
