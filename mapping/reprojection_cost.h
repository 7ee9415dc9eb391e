#pragma once
// Ceres cost functions for bundle adjustment in the rectified stereo camera (pixels).
//
// Parameter blocks, in order: [0] rotation cam_from_world as an Eigen quaternion (x, y, z, w;
// EigenQuaternionManifold), [1] translation cam_from_world (3), [2] point in world (3);
// StereoReprojectionCost only: [3] a change of the rig's disparity correction (offset px, yaw rad,
// and a third entry that nothing depends on and a prior holds at zero: three wide, like the pose's
// blocks, the correction leaves Ceres's fixed-size Schur code in use while it is estimated;
// core/camera/disparity_correction.h), held constant unless bundle adjustment estimates it.
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
#include <memory>

#include <ceres/ceres.h>

#include <Eigen/Core>

#include "core/camera/disparity_correction.h"
#include "core/geometry/rigid3.h"

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

// Solves on one thread without logging, in `ordering` when given (else Ceres finds one);
// returns the iterations taken.
inline int SolveQuietly(ceres::Problem* problem, ceres::LinearSolverType linear_solver,
                        int max_iterations,
                        std::shared_ptr<ceres::ParameterBlockOrdering> ordering = nullptr,
                        double function_tolerance = 1e-6) {
  ceres::Solver::Options options;
  options.function_tolerance = function_tolerance;
  options.linear_solver_type = linear_solver;
  options.linear_solver_ordering = std::move(ordering);
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

// p = R X + t for the parameter layout above, and when `jacobians` is set its derivatives: by
// the rotation block (3x4, its four entries x y z w) and by the point (R). The rotation is the
// unit quaternion's, X + 2 w (v x X) + 2 v x (v x X) with q = (v, w): Ceres keeps the block on
// the unit sphere (EigenQuaternionManifold), and there this formula and its derivatives are
// exact; along the sphere's tangent, the only directions the solver takes, any other extension
// off the sphere has the same derivatives.
struct CameraPoint {
  Eigen::Vector3d p;
  Eigen::Matrix<double, 3, 4> dp_drotation;
  Eigen::Matrix3d dp_dpoint;
};
void TransformToCamera(const double* rotation, const double* translation, const double* point,
                       bool jacobians, CameraPoint* out);

// The correction block's size (above).
constexpr int kCorrectionBlockSize = 3;

// Analytic Jacobians: autodiff's dual numbers cost several times the arithmetic, and bundle
// adjustment evaluates these costs most of its time. Every observation of a stereo bundle
// adjustment has this layout, three residuals, so that Ceres's Schur eliminator runs its
// fixed-size code: one without a right match (LeftOnly) has a disparity row that is always zero.
class StereoReprojectionCost final
    : public ceres::SizedCostFunction<3, 4, 3, 3, kCorrectionBlockSize> {
 public:
  StereoReprojectionCost(const Eigen::Vector2d& left_px, double right_x_px,
                         const RectifiedIntrinsics& k, double disparity_weight);
  // An observation in the left image only: the disparity residual is zero.
  static StereoReprojectionCost* LeftOnly(const Eigen::Vector2d& left_px,
                                          const RectifiedIntrinsics& k);

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;
  // The residuals alone, block by block (the numeric-derivative tests' functor form).
  bool operator()(const double* rotation, const double* translation, const double* point,
                  const double* correction, double* residuals) const;

  static ceres::CostFunction* Create(const Eigen::Vector2d& left_px, double right_x_px,
                                     const RectifiedIntrinsics& k, double disparity_weight) {
    return new StereoReprojectionCost(left_px, right_x_px, k, disparity_weight);
  }

 private:
  Eigen::Vector2d left_px_;
  double disparity_px_;
  double yaw_gain_px_;  // d bias / d yaw at this column: f (1 + x_right^2).
  RectifiedIntrinsics k_;
  double disparity_weight_;  // 0 for a left-only observation.
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
    residuals[2] = correction[2];  // The unused entry (above), held at zero.
    return true;
  }

  static ceres::CostFunction* Create(double offset_sigma_px, double yaw_sigma_rad) {
    return new ceres::AutoDiffCostFunction<DisparityCorrectionPrior, 3, kCorrectionBlockSize>(
        new DisparityCorrectionPrior(offset_sigma_px, yaw_sigma_rad));
  }

 private:
  double offset_sigma_px_, yaw_sigma_rad_;
};

// The left image's residual alone, for maps without stereo (map_adjustment.h).
class MonoReprojectionCost final : public ceres::SizedCostFunction<2, 4, 3, 3> {
 public:
  MonoReprojectionCost(const Eigen::Vector2d& left_px, const RectifiedIntrinsics& k)
      : left_px_(left_px), k_(k) {}

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;
  bool operator()(const double* rotation, const double* translation, const double* point,
                  double* residuals) const;

  static ceres::CostFunction* Create(const Eigen::Vector2d& left_px, const RectifiedIntrinsics& k) {
    return new MonoReprojectionCost(left_px, k);
  }

 private:
  Eigen::Vector2d left_px_;
  RectifiedIntrinsics k_;
};

}  // namespace visloc::mapping
