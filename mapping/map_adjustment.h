#pragma once
// Bundle adjustment of a finished map (after `map merge`, `extend` and `update`): keyframe poses
// and points against the map's observations, with a Huber loss, some keyframes held fixed.
//
// The map keeps mono observations only (raw left-image pixels; the stereo disparities stayed in
// the builder), so:
//   - each observation's residual is measured on the normalized image plane and scaled by fx
//     (pixels at the image centre): the lens is undistorted once, up front, and any lens model
//     works the same;
//   - a point takes part when it has two observations or more and a free keyframe sees it; a
//     point seen by one keyframe alone has no depth constraint left and moves rigidly with its
//     keyframe instead;
//   - the stereo depth is brought back as a prior on every adjusted point: it stays near where
//     its own map's stereo bundle adjustment put it, with a sigma that grows with depth squared
//     as a stereo depth's does. Without it the mono observations of a few nearby keyframes let
//     points slide along their rays;
//   - the fixed keyframes fix the frame (no gauge freedom).
// Which keyframes to hold is the caller's choice; merges hold the first map's first (map_merge.h).

#include <vector>

#include "core/map/map.h"

namespace visloc::mapping {

struct MapAdjustmentOptions {
  double huber_px = 2.0;
  int max_iterations = 20;
  // Afterwards, an observation whose reprojection error is above this (raw pixels) is removed;
  // a point left with none is removed too. 0: keep all.
  double cull_error_px = 4.0;
  // Sigma of the point prior at 1 m depth (metres), scaled by depth^2; 0: no prior. 3 mm: the
  // depth sigma of a 0.1 px disparity with a 10 cm baseline and a 300 px focal length.
  double point_prior_sigma_at_1m_m = 0.003;
};

struct MapAdjustmentStats {
  int free_keyframes = 0;
  int fixed_keyframes = 0;
  int points = 0;               // Points adjusted.
  int moved_with_keyframe = 0;  // Single-view points of free keyframes.
  int point_priors = 0;
  int residual_blocks = 0;  // Reprojection residuals.
  int iterations = 0;
  double initial_rmse_px = 0.0;  // Raw pixels, over the adjusted observations.
  double final_rmse_px = 0.0;
  int culled_observations = 0;
  int culled_points = 0;
  double time_ms = 0.0;
};

// `keyframe_fixed[k]` holds keyframe k's pose; at least one must be fixed. Point indices change
// when points are culled (observations follow); the kernel and appearance index are not touched:
// learn them after.
MapAdjustmentStats AdjustMap(Map* map, const std::vector<bool>& keyframe_fixed,
                             const MapAdjustmentOptions& options);

}  // namespace visloc::mapping
