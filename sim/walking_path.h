#pragma once
// A humanoid's walk as the pattern generator plans it, and the motion it really makes.
//
// The plan is a planar path: segments of walking straight, turning in place, walking along an
// arc, standing, and being carried (a kidnapping: moved without stepping). Each segment follows
// a trapezoidal speed profile (accelerate, cruise, decelerate), so velocity is continuous and
// acceleration finite, which the IMU synthesis relies on.
//
// The true motion adds the gait to the plan: the head bobs vertically at the step frequency,
// sways sideways at half of it, and rolls and pitches slightly (seed paper 001 models exactly
// this oscillation as the humanoid's pattern-generator motion).
//
// Frames: world z up; body frame at the head, between the two cameras: x forward, y left, z up.

#include <vector>

#include "core/geometry/rigid3.h"

namespace visloc::sim {

struct PlanarPose {
  double x = 0.0;
  double y = 0.0;
  double yaw = 0.0;  // Heading, radians, counter-clockwise from +x.
};

struct GaitOptions {
  double speed_mps = 0.22;          // Walking speed (the paper's HRP-2: ~0.2-0.25 m/s).
  double turn_rate_radps = 0.35;    // Turning in place.
  double ramp_s = 0.4;              // Acceleration phase at each segment's start and end.
  double step_frequency_hz = 1.6;   // Steps per second.
  double camera_height_m = 1.45;    // Head height above the floor.
  double bob_amplitude_m = 0.0075;  // Vertical head bob: 1.5 cm peak to peak.
  double sway_amplitude_m = 0.008;  // Lateral sway.
  double roll_amplitude_deg = 1.0;
  double pitch_amplitude_deg = 0.6;
  // Where the head (and the cameras with it) looks, relative to the walking direction: a
  // constant yaw (positive: to the left), plus glances over the shoulder, every
  // glance_period_s a smooth turn out to glance_yaw_rad and back (a raised cosine) lasting
  // glance_s. The plan, and so the planner's odometry, includes the head's turn, as a
  // humanoid's kinematics report the head's motion.
  double head_yaw_rad = 0.0;
  double glance_yaw_rad = 0.0;
  double glance_period_s = 0.0;  // 0: no glances.
  double glance_s = 2.0;
};

class WalkingPath {
 public:
  WalkingPath(const PlanarPose& start, const GaitOptions& gait);

  WalkingPath& Walk(double distance_m);
  WalkingPath& Turn(double angle_rad);                  // Positive: to the left.
  WalkingPath& Arc(double radius_m, double angle_rad);  // Positive angle: curving left.
  WalkingPath& Stand(double duration_s);
  // Moved by (forward, left) metres in the current heading frame and turned by `yaw_rad`,
  // over `duration_s`, without stepping.
  WalkingPath& Carry(double forward_m, double left_m, double yaw_rad, double duration_s);

  double duration_s() const;
  double length_m() const;  // Walked distance (carrying not included).

  // The planned floor pose at time t (clamped to [0, duration]), its yaw the head's
  // (GaitOptions::head_yaw_rad and the glances added to the walking direction).
  PlanarPose PlannedAt(double time_s) const;
  // True while the robot steps (walking or turning), false while standing or carried.
  bool SteppingAt(double time_s) const;
  // Time spent stepping up to t (the integral of the stepping indicator).
  double GaitTimeAt(double time_s) const;
  // The integral of GaitTimeAt from 0 to t.
  double IntegratedGaitTimeAt(double time_s) const;
  // Time intervals [start, end) during which the robot is carried.
  std::vector<std::pair<double, double>> CarriedIntervals() const;

  // The body's true pose in the world (plan + gait), and the plan alone at head height.
  Rigid3d WorldFromBody(double time_s) const;
  Rigid3d PlannedWorldFromBody(double time_s) const;
  // The head's yaw relative to the walking direction at t (GaitOptions::head_yaw_rad, glances).
  double HeadYawAt(double time_s) const;

  const GaitOptions& gait() const { return gait_; }

 private:
  // The walking plan alone: where the feet take the body, its yaw the walking direction.
  PlanarPose WalkingAt(double time_s) const;

  enum class Kind { kWalk, kTurn, kArc, kStand, kCarry };
  struct Segment {
    Kind kind;
    PlanarPose start;
    double distance_m = 0;  // Walk, Arc: path length. Carry: straight-line distance.
    double angle_rad = 0;   // Turn, Arc, Carry: heading change.
    double radius_m = 0;    // Arc.
    Eigen::Vector2d carry_local = Eigen::Vector2d::Zero();
    double duration_s = 0;
    double start_time_s = 0;
  };
  void Append(Segment segment);
  PlanarPose EndOf(const Segment& segment) const;
  // Fraction of the segment completed after `t` seconds of it, with the trapezoidal profile.
  double Progress(const Segment& segment, double t) const;
  double ProfileDuration(double amount, double rate) const;
  const Segment& SegmentAt(double time_s) const;

  GaitOptions gait_;
  PlanarPose start_;
  std::vector<Segment> segments_;
};

}  // namespace visloc::sim
