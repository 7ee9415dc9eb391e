#pragma once
// Map assembly: the SLAM state after global bundle adjustment becomes the map that localization
// loads. Landmarks with enough views become map points with their medoid descriptor; keyframe
// poses and observations move from the rectified world frame to the map frame (the raw left
// camera of the first frame, product.md) with raw pixels, as localization sees them; then the
// visibility kernel is learned (paper 000, sec. 4) and the relocalization vocabulary trained.

#include "core/camera/stereo_rectifier.h"
#include "core/map/map.h"
#include "mapping/bundle_adjustment.h"
#include "mapping/slam_state.h"
#include "mapping/visibility_learning.h"
#include "mapping/vocabulary_builder.h"

namespace visloc::mapping {

struct AssemblyOptions {
  // A landmark becomes a map point when its views count at least this many: a keyframe
  // observation with a stereo match counts two (both cameras saw the point and measured its
  // depth), one without. So a single stereo keyframe is a map of its own.
  int min_views = 2;
  // A landmark observed by one keyframe only, that tracking then expected in at least
  // `cull_min_frames_in_view` frames but found in fewer than `cull_min_found_ratio` of them, was
  // a mismatch or something that moved: left out (as ORB-SLAM culls its new points).
  int cull_min_frames_in_view = 5;
  double cull_min_found_ratio = 0.25;
  VisibilityLearningOptions visibility;
  VocabularyOptions vocabulary;
  void Check() const;
};

struct AssemblyStats {
  int points = 0;
  int culled_unconfirmed = 0;  // Single-keyframe landmarks rarely found again.
  int observations = 0;
  double reprojection_rmse_px = 0.0;  // Left image, over the map's observations.
  double disparity_rmse_px = 0.0;     // Predicted vs measured disparity.
  VisibilityLearningStats visibility;
};

// `map_from_world` takes the SLAM world frame (rectified left camera of the first frame) to the
// map frame, and `rect_from_raw` the raw left camera into the rectified one.
Map AssembleMap(const SlamState& state, const Camera& raw_left_camera,
                const FeatureSettings& features, const MapMetadata& metadata,
                const Rigid3d& map_from_world, const Rigid3d& rect_from_raw,
                const RectifiedIntrinsics& intrinsics, const AssemblyOptions& options,
                AssemblyStats* stats);

}  // namespace visloc::mapping
