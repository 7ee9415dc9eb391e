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

Eigen::Matrix3d Skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

Rigid3d ApplyUpdate(const Vector6d& delta, const Rigid3d& pose) {
  const Eigen::Vector3d phi = delta.tail<3>();
  const double angle = phi.norm();
  const Eigen::Quaterniond rotation =
      angle > 1e-12 ? Eigen::Quaterniond(Eigen::AngleAxisd(angle, phi / angle))
                    : Eigen::Quaterniond::Identity();
  return Rigid3d(rotation * pose.rotation, rotation * pose.translation + delta.head<3>());
}

struct NormalEquations {
  Matrix6d h = Matrix6d::Zero();
  Vector6d g = Vector6d::Zero();
  double robust_cost = 0.0;
  double squared_px = 0.0;
  int residual_count = 0;
};

// Accumulates one scalar residual r (normalized units) with Jacobian row j wrt delta.
void AddResidual(double r, const Eigen::Matrix<double, 1, 6>& j, double huber_normalized,
                 NormalEquations* ne, double focal_px) {
  const double abs_r = std::abs(r);
  const double weight = abs_r <= huber_normalized ? 1.0 : huber_normalized / abs_r;
  ne->h += weight * j.transpose() * j;
  ne->g += weight * r * j.transpose();
  ne->robust_cost +=
      abs_r <= huber_normalized ? r * r : huber_normalized * (2 * abs_r - huber_normalized);
  ne->squared_px += r * r * focal_px * focal_px;
  ++ne->residual_count;
}

NormalEquations Linearize(const Rigid3d& pose, const std::vector<PoseObservation>& observations,
                          const PoseRefineOptions& options) {
  NormalEquations ne;
  const double huber = options.huber_px / options.focal_px;
  for (const PoseObservation& o : observations) {
    const Eigen::Vector3d p = pose * o.point_in_world;
    if (p.z() <= 1e-6) continue;
    const double iz = 1.0 / p.z();
    // d p / d delta = [I | -[p]x].
    Eigen::Matrix<double, 3, 6> dp;
    dp.leftCols<3>().setIdentity();
    dp.rightCols<3>() = -Skew(p);
    const Eigen::Matrix<double, 1, 3> dx(iz, 0, -p.x() * iz * iz);
    const Eigen::Matrix<double, 1, 3> dy(0, iz, -p.y() * iz * iz);
    AddResidual(p.x() * iz - o.normalized.x(), dx * dp, huber, &ne, options.focal_px);
    AddResidual(p.y() * iz - o.normalized.y(), dy * dp, huber, &ne, options.focal_px);
    if (o.has_right) {
      const Eigen::Matrix<double, 1, 3> dxr(iz, 0, -(p.x() - options.baseline_m) * iz * iz);
      AddResidual((p.x() - options.baseline_m) * iz - o.right_x_normalized, dxr * dp, huber, &ne,
                  options.focal_px);
    }
  }
  return ne;
}

double Rmse(const NormalEquations& ne) {
  return ne.residual_count ? std::sqrt(ne.squared_px / ne.residual_count) : 0.0;
}

}  // namespace

double SquaredReprojectionErrorPx(const Rigid3d& cam_from_world, const PoseObservation& o,
                                  const PoseRefineOptions& options) {
  const Eigen::Vector3d p = cam_from_world * o.point_in_world;
  if (p.z() <= 1e-6) return std::numeric_limits<double>::infinity();
  const Eigen::Vector2d e = p.head<2>() / p.z() - o.normalized;
  double squared = e.squaredNorm();
  if (o.has_right) {
    const double ed = options.disparity_weight *
                      (options.baseline_m / p.z() - (o.normalized.x() - o.right_x_normalized));
    squared = std::max(squared, ed * ed);
  }
  return squared * options.focal_px * options.focal_px;
}

Rigid3d RefinePose(const Rigid3d& cam_from_world, const std::vector<PoseObservation>& observations,
                   const PoseRefineOptions& options, PoseRefineStats* stats, Matrix6d* covariance) {
  options.Check();
  Rigid3d pose = cam_from_world;
  PoseRefineStats local;
  NormalEquations ne = Linearize(pose, observations, options);
  local.initial_rmse_px = Rmse(ne);
  double lambda = 1e-4;
  if (observations.size() >= 3) {
    for (int iteration = 0; iteration < options.max_iterations; ++iteration) {
      local.iterations = iteration + 1;
      Matrix6d damped = ne.h;
      damped.diagonal() += lambda * (ne.h.diagonal().array() + 1e-9).matrix();
      const Vector6d delta = damped.ldlt().solve(-ne.g);
      if (!delta.allFinite()) break;
      const Rigid3d candidate = ApplyUpdate(delta, pose);
      const NormalEquations candidate_ne = Linearize(candidate, observations, options);
      if (candidate_ne.robust_cost < ne.robust_cost) {
        // Converged when the step is far below any measurable motion (1e-8 m / rad) or the
        // cost stopped decreasing in its 9th significant digit.
        const bool converged = delta.norm() < 1e-8 ||
                               ne.robust_cost - candidate_ne.robust_cost < 1e-9 * ne.robust_cost;
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
    *covariance = sigma * sigma * ne.h.ldlt().solve(Matrix6d::Identity());
  }
  if (stats) *stats = local;
  return pose;
}

}  // namespace visloc
