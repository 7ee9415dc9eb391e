#pragma once
// Visibility prediction (seed paper 000, sec. 4, eq. 8): the map points a camera at a prior pose
// is likely to see. The K keyframes most similar to the prior pose under the learned kernel
// k(theta, theta_i) (eq. 7) vote for the points they saw:
//   P(v_j = 1 | theta) = sum_i k(theta, theta_i) v_j(theta_i) / sum_i k(theta, theta_i),
// and points with P above the threshold P_t are predicted visible. Only points seen by the K
// keyframes can score above zero, so the cost depends on K, not on the map's size.
//
// The "transparent world" baseline of the paper predicts every map point that projects into
// the image in front of the camera, ignoring occlusion and appearance change.

#include <cstdint>
#include <vector>

#include "core/camera/camera.h"
#include "core/geometry/rigid3.h"
#include "core/map/localization_map.h"

namespace visloc {

struct VisibilityOptions {
  int k = 10;                          // Nearest keyframes (paper: 10). 0: the map's default.
  double probability_threshold = 0.2;  // P_t (paper: 0.2). Negative: the map's default.
  void Check() const;
};

struct PredictedPoint {
  uint32_t point = 0;
  float probability = 0.0f;
};

struct VisibilityStats {
  int keyframes_used = 0;
  int candidates = 0;  // Points seen by those keyframes.
  int predicted = 0;   // Above the threshold.
};

class VisibilityPredictor {
 public:
  // Throws CheckError when the map has no learned kernel (see KernelCueNames).
  VisibilityPredictor(const LocalizationMap& map, const VisibilityOptions& options);

  // Points predicted visible from `map_from_cam`, most probable first.
  std::vector<PredictedPoint> Predict(const Rigid3d& map_from_cam,
                                      VisibilityStats* stats = nullptr) const;
  // The K keyframes with the largest kernel value for the pose, with those values, largest first.
  std::vector<std::pair<int, double>> NearestKeyframes(const Rigid3d& map_from_cam) const;

 private:
  const LocalizationMap& map_;
  int k_;
  double threshold_;
  mutable std::vector<float> votes_;  // Scratch per point, reset after each prediction.
};

// The transparent-world baseline: every point in front of `camera` at `map_from_cam` whose
// projection falls inside the image.
std::vector<uint32_t> PredictTransparentWorld(const LocalizationMap& map, const Camera& camera,
                                              const Rigid3d& map_from_cam);

}  // namespace visloc
