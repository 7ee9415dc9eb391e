#pragma once
// Where up is in a map (MapGravity), from what its recording offers, best first:
//   - the accelerometer: over a window of the run, the specific force turned into the map frame
//     by the camera's poses integrates to the change of velocity minus gravity's, so gravity is
//     what is left once the motion's own velocity change (from the poses) is taken off; with
//     the accelerometer's bias, which the windows tell from gravity where the body turns. A
//     still recording gives gravity plus the bias (its sigma says so), a moving one as well,
//     without a model of its accelerations;
//   - the rig's body declared level (a ground robot's base): its z axis is up;
//   - the floor: the largest plane beneath the keyframes whose normal is near the cameras' mean
//     down direction, checked against the plane the keyframes moved in when they did (a ground
//     robot's), else that motion plane alone.
// Each says how well it knows up (sigma_deg), or why it cannot tell.
//
// Frames: the map frame (the first left camera's); `body` the IMU's (EuRoC's T_BS: body_from_cam).
// Units: metres, seconds, m/s^2, degrees.

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "core/geometry/trajectory.h"
#include "core/map/map.h"

namespace visloc::mapping {

// One IMU reading in the body frame: the specific force (m/s^2; at rest, +9.81 up) and the
// angular rate (rad/s), which carries the body's rotation from one camera pose to the next.
struct ImuReading {
  int64_t timestamp_ns = 0;
  Eigen::Vector3d specific_force_mps2 = Eigen::Vector3d::Zero();
  Eigen::Vector3d angular_rate_radps = Eigen::Vector3d::Zero();
};

struct GravityOptions {
  double gravity_mps2 = 9.81;
  // The accelerometer's bias: its prior (a MEMS IMU's can be half a metre a second squared:
  // EuRoC V1_01's is estimated at 0.55 m/s^2), estimated with gravity where the run turns.
  double accel_bias_sigma_mps2 = 0.3;
  double accel_noise_density = 2.0e-3;  // m/s^2/sqrt(Hz), EuRoC's ADIS16448.
  // The run is cut into windows this long (s), each an equation for gravity and the bias.
  double imu_window_s = 1.0;
  // The direction is never claimed better than this (deg): the map's own keyframe orientations,
  // which turn the samples into the map frame, are known to a few hundredths of a degree.
  double min_imu_sigma_deg = 0.05;
  // Shortest stretch of poses and samples the accelerometer is trusted over.
  double min_imu_duration_s = 1.0;
  // A measured gravity whose magnitude is off by more than this fraction is refused: wrong units,
  // a wrong T_BS, or poses and samples on different clocks.
  double max_magnitude_error = 0.05;
  // The operator's word for a level body (`map build --level-body`): its sigma.
  double level_body_sigma_deg = 1.0;
  // Floor: planes found by RANSAC over the map's points, inlier band (m), and how far from the
  // cameras' mean down direction its normal may be (deg) and how far below the lowest keyframe
  // it must lie (m).
  double floor_band_m = 0.03;
  double floor_max_tilt_from_cameras_deg = 40.0;
  double floor_min_depth_below_m = 0.3;
  int floor_min_points = 60;
  // A floor is level only as well as it was laid, and a map's floor only as well as it was
  // mapped: its up is never claimed better than this (deg).
  double floor_level_sigma_deg = 1.0;
  // What a patch of floor may rise across its width (m): a mat, a ramp, a drain's fall, the
  // pad a robot starts on. Over the patch's narrower width it bounds how well the patch tells
  // level: EuRoC MH_01's start sees 0.7 x 0.9 m of floor, tilted 3.8 deg from the hall's
  // vertical; a room's floor seen across 6 m tells it within half a degree.
  double floor_unevenness_m = 0.05;
  // A floor that tells up no better than this (deg, one sigma) is not taken as the map's up.
  double max_floor_sigma_deg = 2.0;
  int floor_ransac_iterations = 300;
  // Motion plane: the keyframes' positions spread over at least this extent (m) in the plane and
  // at most this fraction of it across it.
  double motion_min_extent_m = 0.5;
  double motion_max_flatness = 0.05;
  // The floor and the motion plane must agree within this (deg) for the floor to be taken.
  double max_floor_motion_disagreement_deg = 5.0;
  uint64_t seed = 1;
};

// What GravityFromImu found, or why it found nothing.
struct GravityResult {
  std::optional<MapGravity> gravity;
  std::string why_not;  // When there is no gravity: the reason, for the build's report.
  double measured_gravity_mps2 = 0.0;  // The accelerometer's gravity magnitude, when measured.
  // The direction's covariance (rad^2, map frame, in the plane tangent to up): loose along the
  // tilts a finding cannot tell (the accelerometer's where its bias is unobservable).
  Eigen::Matrix3d up_covariance_rad2 = Eigen::Matrix3d::Zero();
};

// From the accelerometer. `map_from_cam` is the left camera's pose at each frame of the build
// (sorted by time); samples outside its time span are not used. Between two poses the body's
// rotation is the earlier one carried forward by the gyro: a head that glances 110 degrees in a
// second turns 17 degrees between frames at 5 fps, far from a slerp's path.
GravityResult GravityFromImu(const Trajectory& map_from_cam, const std::vector<ImuReading>& samples,
                             const Rigid3d& body_from_cam, const GravityOptions& options = {});

// From a body the operator declares level: up is its z axis, in the first keyframe's frame.
MapGravity GravityFromLevelBody(const Map& map, const Rigid3d& body_from_cam,
                                const GravityOptions& options = {});

// From the mapped floor and the keyframes' motion plane.
GravityResult GravityFromFloor(const Map& map, const GravityOptions& options = {});

// The accelerometer's up and the floor's (GravityFromFloor's, source kFloor) combined by their
// covariances: a still run leaves the accelerometer's bias in both horizontal tilts and a
// straight one in the tilt across its heading, where a floor seen wide tells level within a
// degree; a run that turns keeps the accelerometer's, which the floor barely moves. Two that
// disagree beyond their uncertainties (a ramp, a floor that is not level, a wrong T_BS) are not
// combined: no gravity, and `why_not` gives the angle between them.
GravityResult CombineImuAndFloor(const GravityResult& imu, const GravityResult& floor,
                                 const GravityOptions& options = {});

}  // namespace visloc::mapping
