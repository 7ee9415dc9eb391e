#pragma once
// Ceres cost functors for bundle adjustment in the rectified stereo camera (pixels).
//
// Parameter blocks, in order: [0] rotation cam_from_world as an Eigen quaternion (x, y, z, w;
// EigenQuaternionManifold), [1] translation cam_from_world (3), [2] point in world (3); stereo
// only: [3] a change of the rig's disparity correction (offset px, yaw rad;
// disparity_correction.h), held constant unless bundle adjustment estimates it.
// With p = R X + t in the rectified left camera:
//   mono:   r = (f p.x / p.z + cx - u, f p.y / p.z + cy - v)
//   stereo: the mono residual plus w (f B / p.z - d + b), the disparity residual, with
//           d = u - u_right the measured disparity and b = offset + f yaw (1 + x_right^2) the
//           bias a change [3] of the disparity correction would take off it. Disparity is measured
//           far more precisely (patch alignment, ~0.04 px) than a keypoint's position (~0.3 px), so
//           it gets its own weight w = sigma_keypoint / sigma_disparity; as a plain right-image
//           residual it would be trusted no more than the keypoint, and depth would drift to fit
//           other views.

#include <array>
#include <cmath>

#include <ceres/ceres.h>
#include <ceres/rotation.h>

#include <Eigen/Core>

#include "core/geometry/rigid3.h"
#include "mapping/disparity_correction.h"

namespace visloc::mapping {

// A pose as the functors' parameter blocks [0] and [1], contiguous: qx qy qz qw tx ty tz of
// cam_from_world.
using PoseBlock = std::array<double, 7>;

inline PoseBlock ToPoseBlock(const Rigid3d& cam_from_world) {
  const Eigen::Quaterniond& q = cam_from_world.rotation;
  const Eigen::Vector3d& t = cam_from_world.translation;
  return {q.x(), q.y(), q.z(), q.w(), t.x(), t.y(), t.z()};
}

inline Rigid3d FromPoseBlock(const PoseBlock& b) {
  return Rigid3d(Eigen::Quaterniond(b[3], b[0], b[1], b[2]), Eigen::Vector3d(b[4], b[5], b[6]));
}

// A pose block in `problem`: the rotation on the unit-quaternion manifold, both blocks held
// when `fixed`. Blocks no residual uses are left alone.
inline void SetUpPoseBlock(ceres::Problem* problem, PoseBlock* pose, bool fixed) {
  if (!problem->HasParameterBlock(pose->data())) return;
  problem->SetManifold(pose->data(), new ceres::EigenQuaternionManifold());
  if (fixed) {
    problem->SetParameterBlockConstant(pose->data());
    problem->SetParameterBlockConstant(pose->data() + 4);
  }
}

// Solves on one thread without logging; returns the iterations taken.
inline int SolveQuietly(ceres::Problem* problem, ceres::LinearSolverType linear_solver,
                        int max_iterations) {
  ceres::Solver::Options options;
  options.linear_solver_type = linear_solver;
  options.max_num_iterations = max_iterations;
  options.num_threads = 1;
  options.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(options, problem, &summary);
  return static_cast<int>(summary.iterations.size());
}

struct RectifiedIntrinsics {
  double f = 1.0;   // Focal length, px (fx = fy after rectification).
  double cx = 0.0;  // Principal point, px.
  double cy = 0.0;
  double baseline_m = 0.0;
};

// p = R X + t for the parameter layout above.
template <typename T>
void TransformToCamera(const T* rotation, const T* translation, const T* point, T* p) {
  // ceres::QuaternionRotatePoint expects (w, x, y, z); Eigen stores (x, y, z, w).
  const T q[4] = {rotation[3], rotation[0], rotation[1], rotation[2]};
  ceres::QuaternionRotatePoint(q, point, p);
  p[0] += translation[0];
  p[1] += translation[1];
  p[2] += translation[2];
}

class StereoReprojectionCost {
 public:
  StereoReprojectionCost(const Eigen::Vector2d& left_px, double right_x_px,
                         const RectifiedIntrinsics& k, double disparity_weight)
      : left_px_(left_px),
        disparity_px_(left_px.x() - right_x_px),
        yaw_gain_px_(k.f * (1.0 + std::pow((right_x_px - k.cx) / k.f, 2))),
        k_(k),
        disparity_weight_(disparity_weight) {}

  template <typename T>
  bool operator()(const T* rotation, const T* translation, const T* point, const T* correction,
                  T* residuals) const {
    T p[3];
    TransformToCamera(rotation, translation, point, p);
    const T inverse_z = T(1.0) / p[2];
    residuals[0] = T(k_.f) * p[0] * inverse_z + T(k_.cx) - T(left_px_.x());
    residuals[1] = T(k_.f) * p[1] * inverse_z + T(k_.cy) - T(left_px_.y());
    const T bias = correction[0] + T(yaw_gain_px_) * correction[1];
    residuals[2] =
        T(disparity_weight_) * (T(k_.f * k_.baseline_m) * inverse_z - T(disparity_px_) + bias);
    return true;
  }

  static ceres::CostFunction* Create(const Eigen::Vector2d& left_px, double right_x_px,
                                     const RectifiedIntrinsics& k, double disparity_weight) {
    return new ceres::AutoDiffCostFunction<StereoReprojectionCost, 3, 4, 3, 3, 2>(
        new StereoReprojectionCost(left_px, right_x_px, k, disparity_weight));
  }

 private:
  Eigen::Vector2d left_px_;
  double disparity_px_;
  double yaw_gain_px_;  // d bias / d yaw at this column: f (1 + x_right^2).
  RectifiedIntrinsics k_;
  double disparity_weight_;
};

// A zero-mean Gaussian prior on a change of the disparity correction, in the units of the
// reprojection residuals (one pixel of keypoint noise): how far it may move with no evidence.
class DisparityCorrectionPrior {
 public:
  DisparityCorrectionPrior(double offset_sigma_px, double yaw_sigma_rad)
      : offset_sigma_px_(offset_sigma_px), yaw_sigma_rad_(yaw_sigma_rad) {}

  template <typename T>
  bool operator()(const T* correction, T* residuals) const {
    residuals[0] = correction[0] / T(offset_sigma_px_);
    residuals[1] = correction[1] / T(yaw_sigma_rad_);
    return true;
  }

  static ceres::CostFunction* Create(double offset_sigma_px, double yaw_sigma_rad) {
    return new ceres::AutoDiffCostFunction<DisparityCorrectionPrior, 2, 2>(
        new DisparityCorrectionPrior(offset_sigma_px, yaw_sigma_rad));
  }

 private:
  double offset_sigma_px_, yaw_sigma_rad_;
};

class MonoReprojectionCost {
 public:
  MonoReprojectionCost(const Eigen::Vector2d& left_px, const RectifiedIntrinsics& k)
      : left_px_(left_px), k_(k) {}

  template <typename T>
  bool operator()(const T* rotation, const T* translation, const T* point, T* residuals) const {
    T p[3];
    TransformToCamera(rotation, translation, point, p);
    residuals[0] = T(k_.f) * p[0] / p[2] + T(k_.cx) - T(left_px_.x());
    residuals[1] = T(k_.f) * p[1] / p[2] + T(k_.cy) - T(left_px_.y());
    return true;
  }

  static ceres::CostFunction* Create(const Eigen::Vector2d& left_px, const RectifiedIntrinsics& k) {
    return new ceres::AutoDiffCostFunction<MonoReprojectionCost, 2, 4, 3, 3>(
        new MonoReprojectionCost(left_px, k));
  }

 private:
  Eigen::Vector2d left_px_;
  RectifiedIntrinsics k_;
};

}  // namespace visloc::mapping
