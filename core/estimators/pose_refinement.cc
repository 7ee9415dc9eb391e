#include "core/estimators/pose_refinement.h"

#include <cmath>
#include <limits>

#include <Eigen/Cholesky>

#include "core/util/check.h"

namespace visloc {

void PoseRefineOptions::Check() const {
  VISLOC_CHECK(focal_px > 0 && huber_px > 0 && pixel_sigma_px > 0 && max_iterations >= 0,
               "pose refinement options");
}

namespace {

using Matrix6d = Eigen::Matrix<double, 6, 6>;
using Vector6d = Eigen::Matrix<double, 6, 1>;

// A pose step (metres and radians together) far below any measurable motion.
constexpr double kNegligibleStep = 1e-8;

Rigid3d ApplyUpdate(const Vector6d& delta, const Rigid3d& pose) {
  const Eigen::Vector3d phi = delta.tail<3>();
  const double angle = phi.norm();
  const Eigen::Quaterniond rotation =
      angle > 1e-12 ? Eigen::Quaterniond(Eigen::AngleAxisd(angle, phi / angle))
                    : Eigen::Quaterniond::Identity();
  return Rigid3d(rotation * pose.rotation, rotation * pose.translation + delta.head<3>());
}

// Gauss-Newton normal equations, accumulated in the 21 entries of the upper triangle (the
// full 6x6 outer product per residual doubled the arithmetic of a linearization).
struct NormalEquations {
  double h_upper[21] = {};
  Vector6d g = Vector6d::Zero();
  double robust_cost = 0.0;
  double squared_px = 0.0;
  int residual_count = 0;

  // One scalar residual r (normalized units) with Jacobian row j (with respect to delta).
  void Add(double r, const double (&j)[6], double huber_normalized, double focal_px) {
    const double abs_r = std::abs(r);
    const double weight = abs_r <= huber_normalized ? 1.0 : huber_normalized / abs_r;
    int k = 0;
    for (int a = 0; a < 6; ++a) {
      const double wa = weight * j[a];
      g(a) += wa * r;
      for (int b = a; b < 6; ++b) h_upper[k++] += wa * j[b];
    }
    robust_cost +=
        abs_r <= huber_normalized ? r * r : huber_normalized * (2 * abs_r - huber_normalized);
    squared_px += r * r * focal_px * focal_px;
    ++residual_count;
  }

  Matrix6d H() const {
    Matrix6d h;
    int k = 0;
    for (int a = 0; a < 6; ++a) {
      for (int b = a; b < 6; ++b) h(a, b) = h(b, a) = h_upper[k++];
    }
    return h;
  }
};

NormalEquations Linearize(const Rigid3d& pose, const std::vector<PoseObservation>& observations,
                          const PoseRefineOptions& options) {
  // The sums are a local copy, returned at the end: accumulated in the returned object itself
  // they stayed in memory, and the loop ran up to 1.4x slower (in the server).
  NormalEquations sum;
  const double huber = options.huber_px / options.focal_px;
  const double focal = options.focal_px;
  const PoseProjector projector(pose, options);
  for (const PoseObservation& o : observations) {
    const Eigen::Vector3d p = projector.ToCamera(o.point_in_world);
    if (p.z() <= 1e-6) continue;
    const double iz = 1.0 / p.z();
    const double u = p.x() * iz, v = p.y() * iz;
    // The rows of u = x/z and v = y/z in closed form: [1/z, 0, -u/z, -uv, 1+u^2, -v] and
    // [0, 1/z, -v/z, -(1+v^2), uv, u].
    // Both rows and residuals are weighed by the lens's pixel scale there (1 for a pinhole).
    const double uv = u * v, s = o.pixel_scale;
    const double ju[6] = {s * iz, 0.0, -s * u * iz, -s * uv, s * (1.0 + u * u), -s * v};
    const double jv[6] = {0.0, s * iz, -s * v * iz, -s * (1.0 + v * v), s * uv, s * u};
    sum.Add(s * (u - o.normalized.x()), ju, huber, focal);
    sum.Add(s * (v - o.normalized.y()), jv, huber, focal);
    if (o.has_right) {
      // The weighted disparity residual w (B / z - (x_left - x_right)) of the measured pair. It
      // depends on z alone: d/dz = -w B / z^2, so its row is [0, 0, dz, dz y, -dz x, 0].
      const double w = options.disparity_weight;
      const double measured_disparity = o.normalized.x() - o.right_x_normalized;
      const double dz = -w * options.baseline_m * iz * iz;
      const double jd[6] = {0.0, 0.0, dz, dz * p.y(), -dz * p.x(), 0.0};
      sum.Add(w * (options.baseline_m * iz - measured_disparity), jd, huber, focal);
    }
  }
  NormalEquations ne = sum;
  return ne;
}

double Rmse(const NormalEquations& ne) {
  return ne.residual_count ? std::sqrt(ne.squared_px / ne.residual_count) : 0.0;
}

// Levenberg-Marquardt over a pose: `linearize(pose)` gives the normal equations there, in
// the left perturbation of that pose's own frame.
template <typename Linearizer>
Rigid3d MinimizeOverPose(const Rigid3d& start, size_t observation_count,
                         const PoseRefineOptions& options, const Linearizer& linearize,
                         PoseRefineStats* stats, Matrix6d* covariance) {
  Rigid3d pose = start;
  PoseRefineStats local;
  NormalEquations ne = linearize(pose);
  local.initial_rmse_px = Rmse(ne);
  double lambda = 1e-4;
  if (observation_count >= 3) {
    for (int iteration = 0; iteration < options.max_iterations; ++iteration) {
      local.iterations = iteration + 1;
      const Matrix6d h = ne.H();
      Matrix6d damped = h;
      damped.diagonal() += lambda * (h.diagonal().array() + 1e-9).matrix();
      const Vector6d delta = damped.ldlt().solve(-ne.g);
      if (!delta.allFinite()) break;
      // Converged when the step is far below any measurable motion, taken or not: at the
      // optimum such a step changes the cost only in its last bits, so it is as often refused,
      // and raising the damping then only shrinks it through every remaining iteration.
      if (delta.norm() < kNegligibleStep) {
        local.converged = true;
        break;
      }
      const Rigid3d candidate = ApplyUpdate(delta, pose);
      const NormalEquations candidate_ne = linearize(candidate);
      if (candidate_ne.robust_cost < ne.robust_cost) {
        // Converged too when the cost stopped decreasing in its 9th significant digit.
        const bool converged = ne.robust_cost - candidate_ne.robust_cost < 1e-9 * ne.robust_cost;
        pose = candidate;
        ne = candidate_ne;
        lambda = std::max(lambda / 10, 1e-9);
        if (converged) {
          local.converged = true;
          break;
        }
      } else {
        lambda *= 10;
        if (lambda > 1e6) {
          local.converged = true;  // no further decrease possible: at a minimum
          break;
        }
      }
    }
  }
  local.final_rmse_px = Rmse(ne);
  if (covariance) {
    const double sigma = options.pixel_sigma_px / options.focal_px;
    *covariance = sigma * sigma * ne.H().ldlt().solve(Matrix6d::Identity());
  }
  if (stats) *stats = local;
  return pose;
}

// The rig's normal equations at `ref_from_world`, from each camera's own: camera c's pose is
// cam_from_ref_c * ref_from_world, and a left perturbation delta of the reference moves it by
// Ad(cam_from_ref_c) delta (Ad = [R, [t]x R; 0, R], translation first), so its rows J become
// J Ad and its sums H and g become Ad^T H Ad and Ad^T g: each observation costs what it costs
// one camera.
NormalEquations LinearizeRig(const Rigid3d& ref_from_world, const RigObservations& rig,
                             const PoseRefineOptions& options) {
  NormalEquations sum;
  Matrix6d h = Matrix6d::Zero();
  for (size_t c = 0; c < rig.per_camera.size(); ++c) {
    if (rig.per_camera[c].empty()) continue;
    const NormalEquations camera =
        Linearize(rig.cam_from_ref[c] * ref_from_world, rig.per_camera[c], options);
    const Matrix6d adjoint = PoseAdjoint(rig.cam_from_ref[c]);
    h += adjoint.transpose() * camera.H() * adjoint;
    sum.g += adjoint.transpose() * camera.g;
    sum.robust_cost += camera.robust_cost;
    sum.squared_px += camera.squared_px;
    sum.residual_count += camera.residual_count;
  }
  int k = 0;
  for (int a = 0; a < 6; ++a) {
    for (int b = a; b < 6; ++b) sum.h_upper[k++] = h(a, b);
  }
  return sum;
}

}  // namespace

Matrix6d PoseAdjoint(const Rigid3d& b_from_a) {
  const Eigen::Matrix3d r = b_from_a.rotation.toRotationMatrix();
  const Eigen::Vector3d& t = b_from_a.translation;
  Eigen::Matrix3d t_cross;
  t_cross << 0, -t.z(), t.y(), t.z(), 0, -t.x(), -t.y(), t.x(), 0;
  Matrix6d adjoint = Matrix6d::Zero();
  adjoint.topLeftCorner<3, 3>() = r;
  adjoint.topRightCorner<3, 3>() = t_cross * r;
  adjoint.bottomRightCorner<3, 3>() = r;
  return adjoint;
}

size_t RigObservations::size() const {
  size_t count = 0;
  for (const auto& camera : per_camera) count += camera.size();
  return count;
}

Rigid3d RefinePose(const Rigid3d& cam_from_world, const std::vector<PoseObservation>& observations,
                   const PoseRefineOptions& options, PoseRefineStats* stats, Matrix6d* covariance) {
  options.Check();
  return MinimizeOverPose(
      cam_from_world, observations.size(), options,
      [&](const Rigid3d& pose) { return Linearize(pose, observations, options); }, stats,
      covariance);
}

Rigid3d RefineRigPose(const Rigid3d& ref_from_world, const RigObservations& rig,
                      const PoseRefineOptions& options, PoseRefineStats* stats,
                      Matrix6d* covariance) {
  options.Check();
  VISLOC_CHECK(rig.per_camera.size() == rig.cam_from_ref.size(), "rig: ", rig.per_camera.size(),
               " observation sets for ", rig.cam_from_ref.size(), " cameras");
  return MinimizeOverPose(
      ref_from_world, rig.size(), options,
      [&](const Rigid3d& pose) { return LinearizeRig(pose, rig, options); }, stats, covariance);
}

}  // namespace visloc
