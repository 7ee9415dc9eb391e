#include "core/estimators/inlier_counter.h"

#include <cstring>
#include <limits>

#include "core/util/cpu_dispatch.h"

namespace visloc {
namespace {

constexpr int kLanes = 8;

// The columns and the pose, for the cloned loop.
struct CountInput {
  const double* x = nullptr;
  const double* y = nullptr;
  const double* z = nullptr;
  const double* nx = nullptr;
  const double* ny = nullptr;
  const double* scale_sq = nullptr;
  const double* disparity = nullptr;
  const long long* has_right = nullptr;
  int n = 0;                    // A multiple of kLanes.
  double r[9] = {}, t[3] = {};  // Row-major rotation and translation of cam_from_world.
  double focal_sq = 0, baseline_m = 0, disparity_weight = 0, threshold_sq = 0;
};

inline void Load(const double* p, Doubles8* v) { std::memcpy(v, p, sizeof *v); }

// The observations within the threshold: PoseProjector::SquaredErrorPx eight observations at
// a time, each lane with its operations in its order. Eigen's 3x3 product (as the library is
// compiled, SSE2) sums the first two rows left to right and the third as r6 x + (r7 y + r8 z),
// then adds the translation (inlier_counter_test.cc holds it to that); nothing is contracted
// into fused multiply-adds (CMakeLists.txt). (Inputs by reference: vector arguments differ
// between the clones' conventions.)
VISLOC_SIMD_CLONES int CountLanes(const CountInput& in) {
  long long count = 0;
  for (int j = 0; j < in.n; j += kLanes) {
    Doubles8 x, y, z, nx, ny, scale_sq, disparity;
    Load(in.x + j, &x);
    Load(in.y + j, &y);
    Load(in.z + j, &z);
    Load(in.nx + j, &nx);
    Load(in.ny + j, &ny);
    Load(in.scale_sq + j, &scale_sq);
    Load(in.disparity + j, &disparity);
    const Doubles8 px = ((in.r[0] * x + in.r[1] * y) + in.r[2] * z) + in.t[0];
    const Doubles8 py = ((in.r[3] * x + in.r[4] * y) + in.r[5] * z) + in.t[1];
    const Doubles8 pz = (in.r[6] * x + (in.r[7] * y + in.r[8] * z)) + in.t[2];
    const Doubles8 iz = 1.0 / pz;
    const Doubles8 ex = px * iz - nx, ey = py * iz - ny;
    Doubles8 squared = (ex * ex + ey * ey) * scale_sq;
    const Doubles8 ed = in.disparity_weight * (in.baseline_m * iz - disparity);
    const Doubles8 ed_sq = ed * ed;
    Int64s8 has_right;
    std::memcpy(&has_right, in.has_right + j, sizeof has_right);
    const Int64s8 take_ed = has_right & (squared < ed_sq);  // std::max(squared, ed^2)
    squared = reinterpret_cast<Doubles8>((take_ed & reinterpret_cast<Int64s8>(ed_sq)) |
                                         (~take_ed & reinterpret_cast<Int64s8>(squared)));
    const Doubles8 scaled = squared * in.focal_sq;
    // The last two comparisons lane by lane: GCC 12 builds their masks a lane at a time in any
    // case, and an eight-lane sum of them cost more than the arithmetic (BM_PnpRansac).
    for (int l = 0; l < kLanes; ++l) count += (pz[l] > 1e-6) & (scaled[l] <= in.threshold_sq);
  }
  return static_cast<int>(count);
}

}  // namespace

InlierCounter::InlierCounter(const std::vector<PoseObservation>& observations,
                             const PoseRefineOptions& options)
    : focal_sq_(options.focal_px * options.focal_px),
      baseline_m_(options.baseline_m),
      disparity_weight_(options.disparity_weight) {
  const int n = static_cast<int>(observations.size());
  padded_ = (n + kLanes - 1) / kLanes * kLanes;
  // Whole vectors: padding points at NaN are behind no camera and in front of none (every
  // comparison with NaN is false), so they are never counted.
  columns_.assign(kColumns * static_cast<size_t>(padded_),
                  std::numeric_limits<double>::quiet_NaN());
  has_right_.assign(padded_, 0);
  for (int i = 0; i < n; ++i) {
    const PoseObservation& o = observations[i];
    column(kX)[i] = o.point_in_world.x();
    column(kY)[i] = o.point_in_world.y();
    column(kZ)[i] = o.point_in_world.z();
    column(kNx)[i] = o.normalized.x();
    column(kNy)[i] = o.normalized.y();
    column(kScaleSq)[i] = o.pixel_scale * o.pixel_scale;
    column(kDisparity)[i] = o.has_right ? o.normalized.x() - o.right_x_normalized : 0.0;
    has_right_[i] = o.has_right ? -1 : 0;
  }
}

int InlierCounter::Count(const Rigid3d& cam_from_world, double max_error_px) const {
  CountInput in;
  in.x = column(kX);
  in.y = column(kY);
  in.z = column(kZ);
  in.nx = column(kNx);
  in.ny = column(kNy);
  in.scale_sq = column(kScaleSq);
  in.disparity = column(kDisparity);
  in.has_right = has_right_.data();
  in.n = padded_;
  const Eigen::Matrix3d rotation = cam_from_world.rotation.toRotationMatrix();
  for (int row = 0; row < 3; ++row) {
    for (int col = 0; col < 3; ++col) in.r[3 * row + col] = rotation(row, col);
    in.t[row] = cam_from_world.translation[row];
  }
  in.focal_sq = focal_sq_;
  in.baseline_m = baseline_m_;
  in.disparity_weight = disparity_weight_;
  in.threshold_sq = max_error_px * max_error_px;
  return CountLanes(in);
}

}  // namespace visloc
