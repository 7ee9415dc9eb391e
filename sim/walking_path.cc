#include "sim/walking_path.h"

#include <algorithm>
#include <cmath>

#include "core/util/check.h"

namespace visloc::sim {

WalkingPath::WalkingPath(const PlanarPose& start, const GaitOptions& gait)
    : gait_(gait), start_(start) {
  VISLOC_CHECK(gait.speed_mps > 0 && gait.turn_rate_radps > 0 && gait.ramp_s >= 0,
               "gait speeds must be positive");
  VISLOC_CHECK(gait.glance_period_s >= 0 &&
                   (gait.glance_period_s == 0 ||
                    (gait.glance_s > 0 && gait.glance_s <= gait.glance_period_s)),
               "glances of ", gait.glance_s, " s every ", gait.glance_period_s, " s");
}

double WalkingPath::ProfileDuration(double amount, double rate) const {
  // A trapezoid with ramps of ramp_s covers rate * (T - ramp_s); short moves use a triangle.
  const double ramp = gait_.ramp_s;
  if (amount <= 0) return 0;
  if (amount >= rate * ramp) return amount / rate + ramp;
  return 2.0 * std::sqrt(amount * ramp / rate);
}

double WalkingPath::Progress(const Segment& segment, double t) const {
  const double total = segment.duration_s;
  if (total <= 0) return 1.0;
  t = std::clamp(t, 0.0, total);
  const double ramp = std::min(gait_.ramp_s, total / 2.0);
  if (ramp <= 0) return t / total;
  // Trapezoidal speed, normalised so the area is 1: peak v satisfies v (total - ramp) = 1.
  const double peak = 1.0 / (total - ramp);
  if (t < ramp) return 0.5 * peak * t * t / ramp;
  if (t > total - ramp) {
    const double remaining = total - t;
    return 1.0 - 0.5 * peak * remaining * remaining / ramp;
  }
  return 0.5 * peak * ramp + peak * (t - ramp);
}

PlanarPose WalkingPath::EndOf(const Segment& s) const {
  PlanarPose end = s.start;
  const double c = std::cos(s.start.yaw), sn = std::sin(s.start.yaw);
  switch (s.kind) {
    case Kind::kWalk:
      end.x += s.distance_m * c;
      end.y += s.distance_m * sn;
      break;
    case Kind::kTurn:
      end.yaw += s.angle_rad;
      break;
    case Kind::kArc: {
      // Centre of the circle to the left (positive angle) of the heading.
      const double signed_radius = s.angle_rad >= 0 ? s.radius_m : -s.radius_m;
      const double cx = s.start.x - signed_radius * sn, cy = s.start.y + signed_radius * c;
      end.yaw += s.angle_rad;
      end.x = cx + signed_radius * std::sin(end.yaw);
      end.y = cy - signed_radius * std::cos(end.yaw);
      break;
    }
    case Kind::kCarry:
      end.x += c * s.carry_local.x() - sn * s.carry_local.y();
      end.y += sn * s.carry_local.x() + c * s.carry_local.y();
      end.yaw += s.angle_rad;
      break;
    case Kind::kStand:
      break;
  }
  return end;
}

void WalkingPath::Append(Segment segment) {
  segment.start = segments_.empty() ? start_ : EndOf(segments_.back());
  segment.start_time_s =
      segments_.empty() ? 0.0 : segments_.back().start_time_s + segments_.back().duration_s;
  segments_.push_back(segment);
}

WalkingPath& WalkingPath::Walk(double distance_m) {
  VISLOC_CHECK(distance_m > 0, "walk distance ", distance_m);
  Segment s{Kind::kWalk, {}};
  s.distance_m = distance_m;
  s.duration_s = ProfileDuration(distance_m, gait_.speed_mps);
  Append(s);
  return *this;
}

WalkingPath& WalkingPath::Turn(double angle_rad) {
  Segment s{Kind::kTurn, {}};
  s.angle_rad = angle_rad;
  s.duration_s = ProfileDuration(std::abs(angle_rad), gait_.turn_rate_radps);
  Append(s);
  return *this;
}

WalkingPath& WalkingPath::Arc(double radius_m, double angle_rad) {
  VISLOC_CHECK(radius_m > 0, "arc radius ", radius_m);
  Segment s{Kind::kArc, {}};
  s.radius_m = radius_m;
  s.angle_rad = angle_rad;
  s.distance_m = radius_m * std::abs(angle_rad);
  s.duration_s = ProfileDuration(s.distance_m, gait_.speed_mps);
  Append(s);
  return *this;
}

WalkingPath& WalkingPath::Stand(double duration_s) {
  Segment s{Kind::kStand, {}};
  s.duration_s = duration_s;
  Append(s);
  return *this;
}

WalkingPath& WalkingPath::Carry(double forward_m, double left_m, double yaw_rad,
                                double duration_s) {
  VISLOC_CHECK(duration_s > 0, "carry duration ", duration_s);
  Segment s{Kind::kCarry, {}};
  s.carry_local = Eigen::Vector2d(forward_m, left_m);
  s.distance_m = s.carry_local.norm();
  s.angle_rad = yaw_rad;
  s.duration_s = duration_s;
  Append(s);
  return *this;
}

double WalkingPath::duration_s() const {
  return segments_.empty() ? 0.0 : segments_.back().start_time_s + segments_.back().duration_s;
}

double WalkingPath::length_m() const {
  double length = 0;
  for (const Segment& s : segments_) {
    if (s.kind == Kind::kWalk || s.kind == Kind::kArc) length += s.distance_m;
  }
  return length;
}

const WalkingPath::Segment& WalkingPath::SegmentAt(double time_s) const {
  VISLOC_CHECK(!segments_.empty(), "empty path");
  for (const Segment& s : segments_) {
    if (time_s < s.start_time_s + s.duration_s) return s;
  }
  return segments_.back();
}

PlanarPose WalkingPath::PlannedAt(double time_s) const {
  PlanarPose pose = WalkingAt(time_s);
  pose.yaw += HeadYawAt(time_s);
  return pose;
}

double WalkingPath::HeadYawAt(double time_s) const {
  double yaw = gait_.head_yaw_rad;
  if (gait_.glance_period_s > 0) {
    // The glance takes the last glance_s of each period: the first comes after a period's walk.
    const double into_glance = std::fmod(std::max(time_s, 0.0), gait_.glance_period_s) -
                               (gait_.glance_period_s - gait_.glance_s);
    if (into_glance > 0) {
      yaw += gait_.glance_yaw_rad * 0.5 * (1.0 - std::cos(2.0 * M_PI * into_glance / gait_.glance_s));
    }
  }
  return yaw;
}

PlanarPose WalkingPath::WalkingAt(double time_s) const {
  if (segments_.empty()) return start_;
  time_s = std::clamp(time_s, 0.0, duration_s());
  const Segment& s = SegmentAt(time_s);
  const double f = Progress(s, time_s - s.start_time_s);
  Segment partial = s;
  partial.distance_m *= f;
  partial.angle_rad *= f;
  partial.carry_local *= f;
  return EndOf(partial);
}

bool WalkingPath::SteppingAt(double time_s) const {
  if (segments_.empty() || time_s < 0 || time_s > duration_s()) return false;
  const Kind kind = SegmentAt(time_s).kind;
  return kind == Kind::kWalk || kind == Kind::kTurn || kind == Kind::kArc;
}

double WalkingPath::GaitTimeAt(double time_s) const {
  double gait_time = 0;
  for (const Segment& s : segments_) {
    if (time_s <= s.start_time_s) break;
    if (s.kind == Kind::kWalk || s.kind == Kind::kTurn || s.kind == Kind::kArc) {
      gait_time += std::min(time_s - s.start_time_s, s.duration_s);
    }
  }
  return gait_time;
}

double WalkingPath::IntegratedGaitTimeAt(double time_s) const {
  // Each stepping segment [a, b) adds 0 before a, (t - a)^2 / 2 inside, and
  // (b - a)^2 / 2 + (b - a)(t - b) after it.
  double integral = 0;
  for (const Segment& s : segments_) {
    if (s.kind != Kind::kWalk && s.kind != Kind::kTurn && s.kind != Kind::kArc) continue;
    const double a = s.start_time_s, b = s.start_time_s + s.duration_s;
    if (time_s <= a) break;
    if (time_s < b) {
      integral += 0.5 * (time_s - a) * (time_s - a);
    } else {
      integral += 0.5 * (b - a) * (b - a) + (b - a) * (time_s - b);
    }
  }
  return integral;
}

std::vector<std::pair<double, double>> WalkingPath::CarriedIntervals() const {
  std::vector<std::pair<double, double>> intervals;
  for (const Segment& s : segments_) {
    if (s.kind == Kind::kCarry)
      intervals.emplace_back(s.start_time_s, s.start_time_s + s.duration_s);
  }
  return intervals;
}

namespace {
// The body frame's orientation for a heading and small roll/pitch (z-up world).
Rigid3d BodyPose(double x, double y, double z, double roll, double pitch, double yaw) {
  return Rigid3d(RotationFromRollPitchYaw(roll, pitch, yaw), Eigen::Vector3d(x, y, z));
}
}  // namespace

Rigid3d WalkingPath::PlannedWorldFromBody(double time_s) const {
  const PlanarPose p = PlannedAt(time_s);
  return BodyPose(p.x, p.y, gait_.camera_height_m, 0, 0, p.yaw);
}

Rigid3d WalkingPath::WorldFromBody(double time_s) const {
  const PlanarPose p = WalkingAt(time_s);
  // The gait fades in and out with the stepping. `share` is the share of [t - w, t + w] spent
  // stepping (w = ramp_s), and the gait phase advances at the step rate times that share, so bob,
  // sway, roll and pitch are smooth (C1): a robot that starts or stops does not jerk, and the IMU
  // sees finite accelerations. The box-filtered share is piecewise linear; smoothstep makes the
  // amplitude envelope C1, since its kinks lie where the share is 0 or 1.
  const double w = std::max(gait_.ramp_s, 1e-3);
  const double share = (GaitTimeAt(time_s + w) - GaitTimeAt(time_s - w)) / (2 * w);
  const double envelope = share * share * (3.0 - 2.0 * share);
  const double smoothed_gait_time =
      (IntegratedGaitTimeAt(time_s + w) - IntegratedGaitTimeAt(time_s - w) -
       IntegratedGaitTimeAt(w) + IntegratedGaitTimeAt(-w)) /
      (2 * w);
  const double phase = 2.0 * M_PI * gait_.step_frequency_hz * smoothed_gait_time;
  const double bob = envelope * gait_.bob_amplitude_m * std::sin(phase);
  const double sway = envelope * gait_.sway_amplitude_m * std::sin(0.5 * phase);
  const double roll = envelope * gait_.roll_amplitude_deg * M_PI / 180 * std::sin(0.5 * phase);
  const double pitch = envelope * gait_.pitch_amplitude_deg * M_PI / 180 * std::sin(phase + 0.6);
  // Sway is sideways with respect to the walking direction; the head turns on top of it.
  return BodyPose(p.x - sway * std::sin(p.yaw), p.y + sway * std::cos(p.yaw),
                  gait_.camera_height_m + bob, roll, pitch, p.yaw + HeadYawAt(time_s));
}

}  // namespace visloc::sim
