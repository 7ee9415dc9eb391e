#pragma once
// Counting a pose hypothesis's inliers, the inner loop of PnP RANSAC: every hypothesis is scored
// against every observation, so on a frame whose matches hold no pose (a lost robot's, where
// RANSAC runs its whole budget) this was the largest part of relocalization's time.

#include <vector>

#include "core/estimators/pose_refinement.h"
#include "core/geometry/rigid3.h"

namespace visloc {

class InlierCounter {
 public:
  // Copies the observations by field (one array per coordinate) so that eight are scored at a
  // time; `options` gives the focal length, the baseline and the disparity weight.
  InlierCounter(const std::vector<PoseObservation>& observations, const PoseRefineOptions& options);

  // The observations whose PoseProjector::SquaredErrorPx under `cam_from_world` is at most
  // `max_error_px` squared, counted with its operations in its order: the same count, to the
  // last rounding.
  int Count(const Rigid3d& cam_from_world, double max_error_px) const;

 private:
  // The fields, one after the other in one allocation (a counter is built per RANSAC call, on
  // every tracked frame), each `padded_` long. Through data(): with no observations there is no
  // element to index.
  enum Column { kX, kY, kZ, kNx, kNy, kScaleSq, kDisparity, kColumns };
  const double* column(Column c) const {
    return columns_.data() + c * static_cast<size_t>(padded_);
  }
  double* column(Column c) { return columns_.data() + c * static_cast<size_t>(padded_); }

  int padded_ = 0;                    // The observations' count rounded up to whole vectors.
  std::vector<double> columns_;       // World point x y z, normalized left x y, pixel_scale
                                      // squared, disparity (nx - right_x_normalized).
  std::vector<long long> has_right_;  // All bits set where there is a right observation.
  double focal_sq_, baseline_m_, disparity_weight_;
};

}  // namespace visloc
