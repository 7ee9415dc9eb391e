#include "mapping/gravity.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include "core/util/check.h"
#include "core/util/random.h"
#include "core/util/strings.h"

namespace visloc::mapping {
namespace {

constexpr double kRadToDeg = 180.0 / M_PI;

double AngleDeg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b)) * kRadToDeg;
}

// A window of consecutive samples that all have a pose, at most GravityOptions::imu_window_s
// long: the integrals over it of the specific force turned into the map frame (m/s) and of the
// body's rotation (s), and its span.
struct Window {
  Eigen::Vector3d force_integral = Eigen::Vector3d::Zero();
  Eigen::Matrix3d rotation_integral = Eigen::Matrix3d::Zero();
  double duration_s = 0.0;
  int64_t start_ns = 0, end_ns = 0;
};

// The body's position at t in the map frame, where the trajectory has a pose.
std::optional<Eigen::Vector3d> BodyPosition(const Trajectory& map_from_cam,
                                            const Rigid3d& cam_from_body, int64_t t_ns,
                                            int64_t max_gap_ns) {
  const auto map_from_cam_t = InterpolateAt(map_from_cam, t_ns, max_gap_ns);
  if (!map_from_cam_t) return std::nullopt;
  return *map_from_cam_t * cam_from_body.translation;
}

// The body's velocity at t (m/s), by differences over `h_ns` inside [start, end].
std::optional<Eigen::Vector3d> BodyVelocity(const Trajectory& map_from_cam,
                                            const Rigid3d& cam_from_body, int64_t t_ns,
                                            int64_t start_ns, int64_t end_ns, int64_t h_ns,
                                            int64_t max_gap_ns) {
  const int64_t before = std::max(start_ns, t_ns - h_ns), after = std::min(end_ns, t_ns + h_ns);
  if (after <= before) return std::nullopt;
  const auto p0 = BodyPosition(map_from_cam, cam_from_body, before, max_gap_ns);
  const auto p1 = BodyPosition(map_from_cam, cam_from_body, after, max_gap_ns);
  if (!p0 || !p1) return std::nullopt;
  return (*p1 - *p0) / NsToSeconds(after - before);
}

// No pose is interpolated across a gap longer than this (frames the build could not track).
constexpr int64_t kMaxGapNs = 500'000'000;
constexpr int64_t kVelocityHalfWindowNs = 100'000'000;
// A velocity from positions a millimetre off over 0.1 s: 1 cm/s.
constexpr double kVelocitySigmaMps = 0.01;

// The run's windows: samples with poses, the body's rotation from the pose before each sample
// carried forward by the gyro.
std::vector<Window> IntegrateWindows(const Trajectory& map_from_cam,
                                     const std::vector<ImuReading>& samples,
                                     const Rigid3d& cam_from_body, const GravityOptions& options) {
  const int64_t first_ns = map_from_cam.front().timestamp_ns;
  const int64_t last_ns = map_from_cam.back().timestamp_ns;
  const int64_t window_ns = SecondsToNs(options.imu_window_s);
  // Rectangle rule over consecutive samples with poses; a sample without one ends a window.
  std::vector<Window> windows;
  bool open = false;
  // The body's rotation at the current sample: the pose of frame `frame` carried forward by
  // the gyro since it (`carried_ns`).
  size_t frame = 0;
  std::optional<size_t> anchored_frame;
  Eigen::Quaterniond map_from_body_q = Eigen::Quaterniond::Identity();
  int64_t carried_ns = 0;
  for (size_t i = 0; i + 1 < samples.size(); ++i) {
    const int64_t t_ns = samples[i].timestamp_ns;
    const int64_t next_ns = samples[i + 1].timestamp_ns;
    while (frame + 1 < map_from_cam.size() && map_from_cam[frame + 1].timestamp_ns <= t_ns) {
      ++frame;
    }
    const bool covered =
        t_ns >= first_ns && next_ns <= last_ns && next_ns > t_ns &&
        frame + 1 < map_from_cam.size() &&
        map_from_cam[frame + 1].timestamp_ns - map_from_cam[frame].timestamp_ns <= kMaxGapNs;
    if (!covered) {
      open = false;
      continue;
    }
    if (anchored_frame != frame) {
      anchored_frame = frame;
      map_from_body_q = map_from_cam[frame].pose.rotation * cam_from_body.rotation;
      carried_ns = map_from_cam[frame].timestamp_ns;
    }
    // Body rates: R(t) = R(t0) Exp(w (t - t0)), w the rate of the sample before t (held over
    // its interval, which holds the stretch since the frame's pose too).
    const Eigen::Vector3d turn =
        samples[i > 0 ? i - 1 : i].angular_rate_radps * NsToSeconds(t_ns - carried_ns);
    if (turn.norm() > 0) {
      map_from_body_q =
          (map_from_body_q * Eigen::Quaterniond(Eigen::AngleAxisd(turn.norm(), turn.normalized())))
              .normalized();
    }
    carried_ns = t_ns;
    if (!open || t_ns - windows.back().start_ns >= window_ns) {
      windows.push_back({});
      windows.back().start_ns = t_ns;
    }
    open = true;
    const double dt_s = NsToSeconds(next_ns - t_ns);
    const Eigen::Matrix3d map_from_body = map_from_body_q.toRotationMatrix();
    Window& window = windows.back();
    window.force_integral += map_from_body * samples[i].specific_force_mps2 * dt_s;
    window.rotation_integral += map_from_body * dt_s;
    window.duration_s += dt_s;
    window.end_ns = next_ns;
  }
  return windows;
}

// Over a window, with the bias b (body frame, constant over the run) and gravity g (map):
//   integral of R (f - b) dt = v(end) - v(start) - g T,
// so e = (F - dv) + T g - (integral of R dt) b = 0.
// Gravity's magnitude is known: without that, a bias along the body's z is gravity wherever
// the body turns about up only (a walk), and the fit trades one for the other. So g = |g| n,
// n a unit vector, and Gauss-Newton over n's two tangent directions and b, b held near zero
// by its prior: a run that turns tells the bias's other components from n, a still one leaves
// them confounded, and the covariance says so.
struct Equation {
  Eigen::Vector3d residual;           // F - dv (m/s).
  Eigen::Matrix3d rotation_integral;  // Integral of R dt (s).
  double duration_s;
  double variance;
};

// Each window's equation (those whose ends have velocities), and the windows' total duration
// and bias-free gravity times it.
std::vector<Equation> WindowEquations(const std::vector<Window>& windows,
                                      const Trajectory& map_from_cam, const Rigid3d& cam_from_body,
                                      const GravityOptions& options, double* duration_s,
                                      Eigen::Vector3d* plain_gravity_times_s) {
  std::vector<Equation> equations;
  *duration_s = 0.0;
  *plain_gravity_times_s = Eigen::Vector3d::Zero();
  for (const Window& window : windows) {
    const auto v0 = BodyVelocity(map_from_cam, cam_from_body, window.start_ns, window.start_ns,
                                 window.end_ns, kVelocityHalfWindowNs, kMaxGapNs);
    const auto v1 = BodyVelocity(map_from_cam, cam_from_body, window.end_ns, window.start_ns,
                                 window.end_ns, kVelocityHalfWindowNs, kMaxGapNs);
    if (!v0 || !v1) continue;
    const Eigen::Vector3d residual = window.force_integral - (*v1 - *v0);
    // Two velocities and the accelerometer's white noise integrated over the window.
    const double variance =
        2 * kVelocitySigmaMps * kVelocitySigmaMps +
        options.accel_noise_density * options.accel_noise_density * window.duration_s;
    equations.push_back({residual, window.rotation_integral, window.duration_s, variance});
    *duration_s += window.duration_s;
    *plain_gravity_times_s -= residual;
  }
  return equations;
}

// Gravity's direction (down, map frame) and the bias fitted to the equations; the direction's
// covariance (rad^2, map frame, in its tangent plane) in `direction_covariance`.
Eigen::Vector3d FitGravityDirection(const std::vector<Equation>& equations,
                                    const Eigen::Vector3d& initial_down,
                                    const GravityOptions& options,
                                    Eigen::Matrix3d* direction_covariance) {
  using Matrix5d = Eigen::Matrix<double, 5, 5>;
  using Vector5d = Eigen::Matrix<double, 5, 1>;
  const double g = options.gravity_mps2;
  const double prior = 1.0 / (options.accel_bias_sigma_mps2 * options.accel_bias_sigma_mps2);
  Eigen::Vector3d down, bias;
  Matrix5d information;
  Eigen::Matrix<double, 3, 2> tangent;  // The last step's basis, which `information` is in.
  // `scale`: the windows' variance over the noise model's.
  const auto solve = [&](double scale) {
    down = initial_down;  // n: gravity's direction.
    bias = Eigen::Vector3d::Zero();
    for (int iteration = 0; iteration < 8; ++iteration) {
      // Tangent basis at n: g(d) = |g| normalize(n + tangent d).
      tangent.col(0) = down.unitOrthogonal();
      tangent.col(1) = down.cross(tangent.col(0));
      information = Matrix5d::Zero();
      Vector5d gradient = Vector5d::Zero();
      information.bottomRightCorner<3, 3>() = prior * Eigen::Matrix3d::Identity();
      gradient.tail<3>() = prior * bias;
      for (const Equation& e : equations) {
        const Eigen::Vector3d error =
            e.residual + e.duration_s * g * down - e.rotation_integral * bias;
        Eigen::Matrix<double, 3, 5> jacobian;
        jacobian << e.duration_s * g * tangent, -e.rotation_integral;
        information += jacobian.transpose() * jacobian / (scale * e.variance);
        gradient += jacobian.transpose() * error / (scale * e.variance);
      }
      const Vector5d step = -information.ldlt().solve(gradient);
      down = (down + tangent * step.head<2>()).normalized();
      bias += step.tail<3>();
      if (step.head<2>().norm() < 1e-9) break;
    }
    // The windows' scatter about the fit over the noise model's (chi^2 per degree of freedom).
    double chi2 = 0.0;
    for (const Equation& e : equations) {
      chi2 += (e.residual + e.duration_s * g * down - e.rotation_integral * bias).squaredNorm() /
              (scale * e.variance);
    }
    return chi2 / std::max(1.0, 3.0 * equations.size() - 5.0);
  };
  // Where the windows scatter more than the noise model says (poses and samples a little off
  // in time, a motion the poses' interpolation smooths), the fit is made again with their
  // measured variance: otherwise directions the data barely sees (the bias a walk hardly
  // turns) are fitted to those errors instead of being held by the bias's prior.
  const double scatter = std::max(1.0, solve(1.0));
  if (scatter > 1.0) solve(scatter);
  *direction_covariance =
      tangent * information.inverse().topLeftCorner<2, 2>() * tangent.transpose();
  return down;
}

}  // namespace

GravityResult GravityFromImu(const Trajectory& map_from_cam, const std::vector<ImuReading>& samples,
                             const Rigid3d& body_from_cam, const GravityOptions& options) {
  GravityResult result;
  if (samples.empty()) {
    result.why_not = "the recording has no accelerometer";
    return result;
  }
  if (map_from_cam.size() < 2) {
    result.why_not = "too few camera poses to turn the accelerometer into the map";
    return result;
  }
  const Rigid3d cam_from_body = body_from_cam.Inverse();
  double duration_s = 0.0;
  Eigen::Vector3d plain_gravity_times_s;  // Without a bias.
  const std::vector<Equation> equations =
      WindowEquations(IntegrateWindows(map_from_cam, samples, cam_from_body, options), map_from_cam,
                      cam_from_body, options, &duration_s, &plain_gravity_times_s);
  if (duration_s < options.min_imu_duration_s) {
    result.why_not =
        StrCat("the accelerometer overlaps the camera poses for ", FormatFixed(duration_s, 2),
               " s, under ", FormatFixed(options.min_imu_duration_s, 1), " s");
    return result;
  }
  // The magnitude, bias-free: a wrong one is wrong units, a wrong T_BS or wrong clocks.
  const double magnitude_mps2 = plain_gravity_times_s.norm() / duration_s;
  result.measured_gravity_mps2 = magnitude_mps2;
  if (std::abs(magnitude_mps2 / options.gravity_mps2 - 1) > options.max_magnitude_error) {
    result.why_not = StrCat("the accelerometer gives gravity of ", FormatFixed(magnitude_mps2, 2),
                            " m/s^2, not ", FormatFixed(options.gravity_mps2, 2),
                            ": its units, the rig's T_BS or the clocks are wrong");
    return result;
  }
  Eigen::Matrix3d direction_covariance;
  const Eigen::Vector3d down = FitGravityDirection(equations, plain_gravity_times_s.normalized(),
                                                   options, &direction_covariance);
  MapGravity found;
  found.source = MapGravity::Source::kImu;
  found.up_in_map = -down;
  // The direction's error per tangent axis (radians: the tangent step is an angle).
  found.sigma_deg =
      std::max(options.min_imu_sigma_deg, std::sqrt(direction_covariance.trace() / 2) * kRadToDeg);
  result.gravity = found;
  result.up_covariance_rad2 = direction_covariance;
  return result;
}

MapGravity GravityFromLevelBody(const Map& map, const Rigid3d& body_from_cam,
                                const GravityOptions& options) {
  const Rigid3d map_from_first =
      map.keyframes.empty() ? Rigid3d() : map.keyframes.front().map_from_cam;
  MapGravity gravity;
  gravity.source = MapGravity::Source::kLevelRig;
  gravity.up_in_map =
      (map_from_first.rotation * body_from_cam.rotation.inverse() * Eigen::Vector3d::UnitZ())
          .normalized();
  gravity.sigma_deg = options.level_body_sigma_deg;
  return gravity;
}

namespace {

// A plane n.x = d with n unit, and how well its normal is known.
struct Plane {
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  double offset = 0.0;
  int inliers = 0;
  double sigma_deg = 0.0;
  // The points' spread (rms, m) along the normal, then the two in-plane principal directions.
  Eigen::Vector3d spread_m = Eigen::Vector3d::Zero();
  // The width (m) along in-plane direction i (0: the wider, 1: the narrower) of points spread
  // evenly with this rms.
  double width_m(int i) const { return std::sqrt(12.0) * spread_m(2 - i); }
};

// An even covariance (rad^2) of `sigma_deg` in the plane tangent to unit `up`.
Eigen::Matrix3d TangentCovariance(const Eigen::Vector3d& up, double sigma_deg) {
  const double sigma_rad = sigma_deg / kRadToDeg;
  return sigma_rad * sigma_rad * (Eigen::Matrix3d::Identity() - up * up.transpose());
}

// How well a found floor tells up (deg): the fit's, the floor's laying, and the patch's own
// rise across its narrower width.
double FloorSigmaDeg(const Plane& floor, const GravityOptions& options) {
  const double patch_deg =
      std::atan2(options.floor_unevenness_m, std::max(1e-3, floor.width_m(1))) * kRadToDeg;
  return std::sqrt(floor.sigma_deg * floor.sigma_deg +
                   options.floor_level_sigma_deg * options.floor_level_sigma_deg +
                   patch_deg * patch_deg);
}

// Least-squares plane through `points` (at least 3): the normal is the direction of least
// spread; its sigma from the residual and the spread across the plane.
Plane FitPlane(const std::vector<Eigen::Vector3d>& points) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& p : points) mean += p;
  mean /= static_cast<double>(points.size());
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (const Eigen::Vector3d& p : points) scatter += (p - mean) * (p - mean).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(scatter / points.size());
  Plane plane;
  plane.normal = eigen.eigenvectors().col(0);
  plane.offset = plane.normal.dot(mean);
  plane.inliers = static_cast<int>(points.size());
  plane.spread_m = eigen.eigenvalues().cwiseMax(0.0).cwiseSqrt();
  // The normal's tilt: residual rms over the in-plane spread, shrunk by sqrt(N).
  plane.sigma_deg = plane.spread_m(0) / std::max(1e-6, plane.spread_m(1)) /
                    std::sqrt(static_cast<double>(points.size())) * kRadToDeg;
  return plane;
}

// The keyframes' mean down direction (each camera's +y, OpenCV), map frame.
Eigen::Vector3d CamerasDown(const Map& map) {
  Eigen::Vector3d down = Eigen::Vector3d::Zero();
  for (const Keyframe& k : map.keyframes) {
    down += k.map_from_cam.rotation * Eigen::Vector3d::UnitY();
  }
  return down.normalized();
}

// The largest plane beneath every keyframe whose upward normal is near the cameras' up.
std::optional<Plane> FindFloor(const Map& map, const Eigen::Vector3d& cameras_up,
                               const GravityOptions& options) {
  const int n = static_cast<int>(map.points.size());
  if (n < options.floor_min_points) return std::nullopt;
  Rng rng(options.seed);
  const double max_tilt_rad = options.floor_max_tilt_from_cameras_deg / kRadToDeg;
  std::optional<Plane> best;
  for (int iteration = 0; iteration < options.floor_ransac_iterations; ++iteration) {
    const Eigen::Vector3d& a = map.points[rng.UniformInt(0, n - 1)].position_in_map;
    const Eigen::Vector3d& b = map.points[rng.UniformInt(0, n - 1)].position_in_map;
    const Eigen::Vector3d& c = map.points[rng.UniformInt(0, n - 1)].position_in_map;
    Eigen::Vector3d normal = (b - a).cross(c - a);
    if (normal.norm() < 1e-9) continue;
    normal.normalize();
    if (normal.dot(cameras_up) < 0) normal = -normal;
    if (std::acos(std::clamp(normal.dot(cameras_up), -1.0, 1.0)) > max_tilt_rad) continue;
    const double offset = normal.dot(a);
    // Every keyframe well above it: a floor, not a wall or a table the cameras passed under.
    bool beneath = true;
    for (const Keyframe& k : map.keyframes) {
      if (normal.dot(k.map_from_cam.translation) - offset < options.floor_min_depth_below_m) {
        beneath = false;
        break;
      }
    }
    if (!beneath) continue;
    int inliers = 0;
    for (const MapPoint& p : map.points) {
      inliers += std::abs(normal.dot(p.position_in_map) - offset) <= options.floor_band_m;
    }
    if (!best || inliers > best->inliers) best = Plane{normal, offset, inliers, 0.0};
  }
  if (!best || best->inliers < options.floor_min_points) return std::nullopt;
  // Refined on its inliers, twice (the refit takes in what the sample's plane missed).
  for (int pass = 0; pass < 2; ++pass) {
    std::vector<Eigen::Vector3d> inliers;
    for (const MapPoint& p : map.points) {
      if (std::abs(best->normal.dot(p.position_in_map) - best->offset) <= options.floor_band_m) {
        inliers.push_back(p.position_in_map);
      }
    }
    if (static_cast<int>(inliers.size()) < options.floor_min_points) return std::nullopt;
    Plane refit = FitPlane(inliers);
    if (refit.normal.dot(cameras_up) < 0) {
      refit.normal = -refit.normal;
      refit.offset = -refit.offset;
    }
    best = refit;
  }
  return best;
}

// The plane the keyframes moved in, when they spread over one and kept to it.
std::optional<Plane> FindMotionPlane(const Map& map, const Eigen::Vector3d& cameras_up,
                                     const GravityOptions& options, std::string* why_not) {
  std::vector<Eigen::Vector3d> centres;
  for (const Keyframe& k : map.keyframes) centres.push_back(k.map_from_cam.translation);
  if (centres.size() < 3) {
    *why_not = "fewer than 3 keyframes";
    return std::nullopt;
  }
  Plane plane = FitPlane(centres);
  const Eigen::Vector3d& spread = plane.spread_m;
  if (2 * spread(1) < options.motion_min_extent_m) {
    *why_not = StrCat("the keyframes spread over ", FormatFixed(2 * spread(1), 2),
                      " m across their second direction, too little to span a plane");
    return std::nullopt;
  }
  if (spread(0) > options.motion_max_flatness * spread(1)) {
    *why_not = StrCat("the keyframes did not keep to a plane (", FormatFixed(spread(0) * 100, 1),
                      " cm across it)");
    return std::nullopt;
  }
  if (plane.normal.dot(cameras_up) < 0) plane.normal = -plane.normal;
  if (plane.normal.dot(cameras_up) < std::cos(60.0 / kRadToDeg)) {
    *why_not = "the keyframes' plane is not the cameras' floor (its normal is far from their up)";
    return std::nullopt;
  }
  return plane;
}

}  // namespace

GravityResult GravityFromFloor(const Map& map, const GravityOptions& options) {
  GravityResult result;
  if (map.keyframes.empty()) {
    result.why_not = "the map has no keyframes";
    return result;
  }
  const Eigen::Vector3d cameras_up = -CamerasDown(map);
  const std::optional<Plane> floor = FindFloor(map, cameras_up, options);
  std::string motion_why_not;
  const std::optional<Plane> motion = FindMotionPlane(map, cameras_up, options, &motion_why_not);
  MapGravity gravity;
  if (floor && motion) {
    const double disagreement_deg = AngleDeg(floor->normal, motion->normal);
    if (disagreement_deg > options.max_floor_motion_disagreement_deg) {
      result.why_not = StrCat("the floor and the keyframes' motion plane disagree by ",
                              FormatFixed(disagreement_deg, 1), " deg");
      return result;
    }
  }
  std::string floor_why_not;
  if (floor) {
    gravity.source = MapGravity::Source::kFloor;
    gravity.up_in_map = floor->normal;
    gravity.sigma_deg = FloorSigmaDeg(*floor, options);
    result.up_covariance_rad2 = TangentCovariance(floor->normal, gravity.sigma_deg);
    if (gravity.sigma_deg > options.max_floor_sigma_deg) {
      floor_why_not = StrCat("the floor seen spans only ", FormatFixed(floor->width_m(1), 1), " x ",
                             FormatFixed(floor->width_m(0), 1), " m: level within ",
                             FormatFixed(gravity.sigma_deg, 1), " deg, over the ",
                             FormatFixed(options.max_floor_sigma_deg, 1), " deg taken");
    }
  }
  if (floor && floor_why_not.empty()) {
    // Taken as found.
  } else if (motion) {
    gravity.source = MapGravity::Source::kMotionPlane;
    gravity.up_in_map = motion->normal;
    // A walking robot's head bobs and a wheeled one's floor is not flat: a degree at least.
    gravity.sigma_deg = std::max(1.0, motion->sigma_deg);
    result.up_covariance_rad2 = TangentCovariance(motion->normal, gravity.sigma_deg);
  } else {
    result.why_not =
        StrCat(floor_why_not.empty() ? "no floor beneath the keyframes" : floor_why_not, ", and ",
               motion_why_not);
    return result;
  }
  result.gravity = gravity;
  return result;
}

GravityResult CombineImuAndFloor(const GravityResult& imu, const GravityResult& floor,
                                 const GravityOptions& options) {
  VISLOC_CHECK(imu.gravity && imu.gravity->source == MapGravity::Source::kImu && floor.gravity &&
                   floor.gravity->source == MapGravity::Source::kFloor,
               "CombineImuAndFloor takes the accelerometer's up and the floor's");
  // Both as small tilts (rad) in a basis tangent at the accelerometer's up: it at 0, the floor
  // at its direction's tangent coordinates.
  const Eigen::Vector3d& imu_up = imu.gravity->up_in_map;
  Eigen::Matrix<double, 3, 2> tangent;
  tangent.col(0) = imu_up.unitOrthogonal();
  tangent.col(1) = imu_up.cross(tangent.col(0));
  const Eigen::Vector2d floor_tilt = tangent.transpose() * floor.gravity->up_in_map;
  // The accelerometer's covariance never below its floor (GravityOptions::min_imu_sigma_deg).
  const double min_rad = options.min_imu_sigma_deg / kRadToDeg;
  const Eigen::Matrix2d imu_covariance = tangent.transpose() * imu.up_covariance_rad2 * tangent +
                                         min_rad * min_rad * Eigen::Matrix2d::Identity();
  const Eigen::Matrix2d floor_covariance = tangent.transpose() * floor.up_covariance_rad2 * tangent;
  GravityResult result;
  result.measured_gravity_mps2 = imu.measured_gravity_mps2;
  const double disagreement_deg = AngleDeg(imu_up, floor.gravity->up_in_map);
  // Chi-square of 2 degrees of freedom at 99.9%.
  constexpr double kMaxMahalanobis2 = 13.82;
  if (floor_tilt.dot((imu_covariance + floor_covariance).ldlt().solve(floor_tilt)) >
      kMaxMahalanobis2) {
    result.why_not =
        StrCat("the floor and the accelerometer disagree by ", FormatFixed(disagreement_deg, 2),
               " deg, beyond their sigmas (", FormatFixed(imu.gravity->sigma_deg, 2), " and ",
               FormatFixed(floor.gravity->sigma_deg, 2), " deg)");
    return result;
  }
  const Eigen::Matrix2d imu_information = imu_covariance.inverse();
  const Eigen::Matrix2d floor_information = floor_covariance.inverse();
  const Eigen::Matrix2d covariance = (imu_information + floor_information).inverse();
  const Eigen::Vector2d tilt = covariance * (floor_information * floor_tilt);
  MapGravity combined;
  combined.source = MapGravity::Source::kImuAndFloor;
  combined.up_in_map = (imu_up + tangent * tilt).normalized();
  combined.sigma_deg =
      std::max(options.min_imu_sigma_deg, std::sqrt(covariance.trace() / 2) * kRadToDeg);
  result.gravity = combined;
  result.up_covariance_rad2 = tangent * covariance * tangent.transpose();
  return result;
}

}  // namespace visloc::mapping
