#include "core/estimators/p3p.h"

#include <cmath>

#include <Eigen/Geometry>

namespace visloc {
namespace {

// The largest real root of z^3 + a z^2 + b z + c (Cardano, or the trigonometric form when all
// three roots are real).
double LargestCubicRoot(double a, double b, double c) {
  const double p = b - a * a / 3.0;
  const double q = 2.0 * a * a * a / 27.0 - a * b / 3.0 + c;
  const double discriminant = q * q / 4.0 + p * p * p / 27.0;
  double z;
  if (discriminant >= 0) {
    const double root = std::sqrt(discriminant);
    z = std::cbrt(-q / 2.0 + root) + std::cbrt(-q / 2.0 - root);
  } else {  // p < 0 here.
    const double r = std::sqrt(-p / 3.0);
    const double cos_phi = std::clamp(-q / (2.0 * r * r * r), -1.0, 1.0);
    z = 2.0 * r * std::cos(std::acos(cos_phi) / 3.0);
  }
  return z - a / 3.0;
}

// Newton steps on the quartic from `x` (the closed form loses digits when roots are close).
double PolishQuarticRoot(const std::array<double, 5>& c, double x) {
  for (int i = 0; i < 2; ++i) {
    const double f = (((c[0] * x + c[1]) * x + c[2]) * x + c[3]) * x + c[4];
    const double df = ((4 * c[0] * x + 3 * c[1]) * x + 2 * c[2]) * x + c[3];
    if (std::abs(df) < 1e-300) break;
    x -= f / df;
  }
  return x;
}

// Orthonormal axes on a triangle: its first edge, the in-plane normal to it, the plane normal.
// False for a degenerate (collinear or coincident) triangle.
bool TriangleAxes(const std::array<Eigen::Vector3d, 3>& p, Eigen::Matrix3d* axes) {
  const Eigen::Vector3d e1 = p[1] - p[0];
  const Eigen::Vector3d n = e1.cross(p[2] - p[0]);
  if (e1.norm() < 1e-12 || n.norm() < 1e-12 * e1.squaredNorm()) return false;
  axes->col(0) = e1.normalized();
  axes->col(2) = n.normalized();
  axes->col(1) = axes->col(2).cross(axes->col(0));
  return true;
}

}  // namespace

int SolveQuartic(const std::array<double, 5>& c, std::array<double, 4>* roots) {
  if (c[0] == 0.0) return 0;  // Not a quartic (see the header).
  // Monic x^4 + b x^3 + cc x^2 + d x + e, then depressed with x = y - b/4:
  // y^4 + p y^2 + q y + r.
  const double b = c[1] / c[0], cc = c[2] / c[0], d = c[3] / c[0], e = c[4] / c[0];
  const double b2 = b * b;
  const double p = cc - 3.0 * b2 / 8.0;
  const double q = d - b * cc / 2.0 + b2 * b / 8.0;
  const double r = e - b * d / 4.0 + b2 * cc / 16.0 - 3.0 * b2 * b2 / 256.0;
  int count = 0;
  const auto add_quadratic = [&](double linear, double constant) {  // y^2 + linear y + constant
    const double discriminant = linear * linear - 4.0 * constant;
    if (discriminant < 0) return;
    const double root = std::sqrt(discriminant);
    (*roots)[count++] = (-linear + root) / 2.0 - b / 4.0;
    (*roots)[count++] = (-linear - root) / 2.0 - b / 4.0;
  };
  // Ferrari: y^4 + p y^2 + q y + r = (y^2 + p/2 + m)^2 - (2m y^2 - q y + m^2 + p m + p^2/4 - r),
  // and the second term is a perfect square when m solves the resolvent cubic
  // m^3 + p m^2 + (p^2/4 - r) m - q^2/8 = 0 (which has a positive root when q != 0).
  const double m = LargestCubicRoot(p, p * p / 4.0 - r, -q * q / 8.0);
  if (m > 1e-14) {
    const double s = std::sqrt(2.0 * m);
    add_quadratic(s, p / 2.0 + m - q / (2.0 * s));
    add_quadratic(-s, p / 2.0 + m + q / (2.0 * s));
  } else {  // Biquadratic: y^4 + p y^2 + r, y^2 = (-p +- sqrt(p^2 - 4r)) / 2.
    const double discriminant = p * p - 4.0 * r;
    if (discriminant >= 0) {
      for (double y2 :
           {(-p + std::sqrt(discriminant)) / 2.0, (-p - std::sqrt(discriminant)) / 2.0}) {
        if (y2 < 0) continue;
        (*roots)[count++] = std::sqrt(y2) - b / 4.0;
        (*roots)[count++] = -std::sqrt(y2) - b / 4.0;
      }
    }
  }
  for (int i = 0; i < count; ++i) (*roots)[i] = PolishQuarticRoot(c, (*roots)[i]);
  return count;
}

std::vector<Rigid3d> SolveP3P(const std::array<Eigen::Vector3d, 3>& points_in_world,
                              const std::array<Eigen::Vector2d, 3>& normalized) {
  std::array<Eigen::Vector3d, 3> rays;
  for (int i = 0; i < 3; ++i) rays[i] = normalized[i].homogeneous().normalized();
  // Squared side lengths opposite each point, and the cosines of the angles between the rays.
  const double a2 = (points_in_world[1] - points_in_world[2]).squaredNorm();
  const double b2 = (points_in_world[0] - points_in_world[2]).squaredNorm();
  const double c2 = (points_in_world[0] - points_in_world[1]).squaredNorm();
  if (a2 < 1e-18 || b2 < 1e-18 || c2 < 1e-18) return {};
  const double cos_alpha = rays[1].dot(rays[2]);
  const double cos_beta = rays[0].dot(rays[2]);
  const double cos_gamma = rays[0].dot(rays[1]);
  // Haralick et al. (1994), eq. (9): the quartic A4 v^4 + ... + A0 in v = s3 / s1.
  const double p = (a2 - c2) / b2, q = (a2 + c2) / b2;
  const double ca2 = cos_alpha * cos_alpha, cb2 = cos_beta * cos_beta, cg2 = cos_gamma * cos_gamma;
  const double abg = cos_alpha * cos_beta * cos_gamma;
  const std::array<double, 5> quartic = {
      (p - 1) * (p - 1) - 4 * c2 / b2 * ca2,
      4 * (p * (1 - p) * cos_beta - (1 - q) * cos_alpha * cos_gamma + 2 * c2 / b2 * ca2 * cos_beta),
      2 * (p * p - 1 + 2 * p * p * cb2 + 2 * (b2 - c2) / b2 * ca2 - 4 * q * abg +
           2 * (b2 - a2) / b2 * cg2),
      4 * (-p * (1 + p) * cos_beta + 2 * a2 / b2 * cg2 * cos_beta -
           (1 - q) * cos_alpha * cos_gamma),
      (1 + p) * (1 + p) - 4 * a2 / b2 * cg2};
  if (std::abs(quartic[0]) < 1e-12 * (std::abs(quartic[4]) + 1e-300)) return {};
  // The camera triangle is congruent to the world one by construction, so the motion between
  // them is exact from the two triangles' axes. (AlignRigid, the general least-squares
  // alignment, gives the same pose but costs 5x as much per hypothesis, in heap allocations and
  // an SVD: BM_SolveP3P 1.6 us against 0.3 us.)
  Eigen::Matrix3d world_axes;
  if (!TriangleAxes(points_in_world, &world_axes)) return {};
  std::array<double, 4> roots;
  const int count = SolveQuartic(quartic, &roots);
  std::vector<Rigid3d> solutions;
  for (int i = 0; i < count; ++i) {
    const double v = roots[i];
    if (v <= 0) continue;  // Behind the camera.
    const double denominator = 2 * (cos_gamma - v * cos_alpha);
    if (std::abs(denominator) < 1e-12) continue;
    const double u = ((p - 1) * v * v - 2 * p * cos_beta * v + 1 + p) / denominator;
    const double s1_sq = b2 / (1 + v * v - 2 * v * cos_beta);
    if (u <= 0 || !(s1_sq > 0)) continue;
    const double s1 = std::sqrt(s1_sq);
    const std::array<Eigen::Vector3d, 3> in_cam = {s1 * rays[0], u * s1 * rays[1],
                                                   v * s1 * rays[2]};
    Eigen::Matrix3d cam_axes;
    if (!TriangleAxes(in_cam, &cam_axes)) continue;
    const Eigen::Matrix3d rotation = cam_axes * world_axes.transpose();
    const Rigid3d pose(rotation, in_cam[0] - rotation * points_in_world[0]);
    // Duplicate roots (a double root split by rounding) give the same pose.
    bool duplicate = false;
    for (const Rigid3d& s : solutions) {
      duplicate |= (s.translation - pose.translation).norm() < 1e-9 &&
                   s.rotation.angularDistance(pose.rotation) < 1e-9;
    }
    if (!duplicate && pose.translation.allFinite()) solutions.push_back(pose);
  }
  return solutions;
}

}  // namespace visloc
