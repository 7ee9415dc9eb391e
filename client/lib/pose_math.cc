#include "client/lib/pose_math.h"

#include <cmath>

namespace visloc::client {
namespace {

struct Quaternion {
  double w, x, y, z;
};

Quaternion RotationOf(const v1::Pose& p) {
  const double n = std::sqrt(p.qw() * p.qw() + p.qx() * p.qx() + p.qy() * p.qy() + p.qz() * p.qz());
  if (!(n > 0)) return {1, 0, 0, 0};
  return {p.qw() / n, p.qx() / n, p.qy() / n, p.qz() / n};
}

Quaternion Multiply(const Quaternion& a, const Quaternion& b) {
  return {a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z,
          a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y,
          a.w * b.y - a.x * b.z + a.y * b.w + a.z * b.x,
          a.w * b.z + a.x * b.y - a.y * b.x + a.z * b.w};
}

// q * v * conj(q) for a unit quaternion.
void Rotate(const Quaternion& q, const double v[3], double out[3]) {
  const Quaternion p{0, v[0], v[1], v[2]};
  const Quaternion r = Multiply(Multiply(q, p), {q.w, -q.x, -q.y, -q.z});
  out[0] = r.x;
  out[1] = r.y;
  out[2] = r.z;
}

v1::Pose Make(const Quaternion& q, const double t[3]) {
  v1::Pose p;
  p.set_qw(q.w);
  p.set_qx(q.x);
  p.set_qy(q.y);
  p.set_qz(q.z);
  p.set_tx(t[0]);
  p.set_ty(t[1]);
  p.set_tz(t[2]);
  return p;
}

}  // namespace

v1::Pose Compose(const v1::Pose& a_from_b, const v1::Pose& b_from_c) {
  const Quaternion q_ab = RotationOf(a_from_b);
  const double t_bc[3] = {b_from_c.tx(), b_from_c.ty(), b_from_c.tz()};
  double t[3];
  Rotate(q_ab, t_bc, t);
  t[0] += a_from_b.tx();
  t[1] += a_from_b.ty();
  t[2] += a_from_b.tz();
  return Make(Multiply(q_ab, RotationOf(b_from_c)), t);
}

v1::Pose Invert(const v1::Pose& a_from_b) {
  const Quaternion q = RotationOf(a_from_b);
  const Quaternion inverse{q.w, -q.x, -q.y, -q.z};
  const double t_ab[3] = {a_from_b.tx(), a_from_b.ty(), a_from_b.tz()};
  double t[3];
  Rotate(inverse, t_ab, t);
  for (double& v : t) v = -v;
  return Make(inverse, t);
}

v1::Pose PropagateByOdometry(const v1::Pose& map_from_cam_then, const v1::Pose& odom_from_cam_then,
                             const v1::Pose& odom_from_cam_now) {
  return Compose(map_from_cam_then, Compose(Invert(odom_from_cam_then), odom_from_cam_now));
}

}  // namespace visloc::client
