#pragma once
// Rigid-body transforms with frame-explicit naming.
//
// A Rigid3d named `a_from_b` maps coordinates of a point in frame b into frame a:
//   point_in_a = a_from_b * point_in_b.
// Composition reads right to left: a_from_c = a_from_b * b_from_c. A camera pose in the map
// (product.md's T_map_cam) is `map_from_cam`: its translation is the camera centre in the map.
// Rotations are unit Hamilton quaternions (Eigen's convention); translations are metres.

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace visloc {

struct Rigid3d {
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();

  Rigid3d() = default;
  Rigid3d(const Eigen::Quaterniond& rotation_in, const Eigen::Vector3d& translation_in)
      : rotation(rotation_in.normalized()), translation(translation_in) {}
  Rigid3d(const Eigen::Matrix3d& rotation_matrix, const Eigen::Vector3d& translation_in)
      : rotation(Eigen::Quaterniond(rotation_matrix).normalized()), translation(translation_in) {}

  static Rigid3d Identity() { return Rigid3d(); }
  // From a 3x4 or 4x4 homogeneous matrix [R | t]; the rotation block is re-orthonormalized.
  static Rigid3d FromMatrix(const Eigen::Matrix<double, 3, 4>& matrix);

  Eigen::Matrix<double, 3, 4> ToMatrix3x4() const;
  Eigen::Matrix4d ToMatrix4() const;

  Rigid3d Inverse() const;
  Eigen::Vector3d operator*(const Eigen::Vector3d& point) const {
    return rotation * point + translation;
  }
};

inline Rigid3d operator*(const Rigid3d& a_from_b, const Rigid3d& b_from_c) {
  return Rigid3d(a_from_b.rotation * b_from_c.rotation,
                 a_from_b.translation + a_from_b.rotation * b_from_c.translation);
}

// The cross-product matrix [v]x, so that [v]x a = v x a.
inline Eigen::Matrix3d Skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

// Interpolates between two poses at fraction `t` in [0, 1]: slerp for the rotation, linear for
// the translation (the usual choice for densely sampled trajectories).
Rigid3d Interpolate(const Rigid3d& start, const Rigid3d& end, double t);

// The rotation angle of `rotation` in degrees, in [0, 180].
double RotationAngleDeg(const Eigen::Quaterniond& rotation);

// Rotation from roll (about x), pitch (about y) and yaw (about z), radians, composed as
// R = Rz(yaw) * Ry(pitch) * Rx(roll): the aerospace/ROS convention for a z-up body frame.
Eigen::Quaterniond RotationFromRollPitchYaw(double roll, double pitch, double yaw);

// True when the two transforms agree within the tolerances (metres, degrees).
bool ApproxEqual(const Rigid3d& a, const Rigid3d& b, double translation_tol_m,
                 double rotation_tol_deg);

}  // namespace visloc
