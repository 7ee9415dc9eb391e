#pragma once
// A map brought up to date with a new session through a place that changed (`visloc map
// update`): furniture moved, boxes gone, new things standing around.
//
//   1. the session (mapped on its own from stereo) is registered to the map (map_merge.h), near
//      a guess when one is given (its images localized in the map, session_registration.h);
//   2. every map point is checked against the session's keyframes: a keyframe "should see" the
//      point when it projects into its image, in front and within `max_depth_m`, seen from a
//      direction within `max_view_angle_deg` of the directions the map saw it from; it "sees"
//      it when the session reconstructed a point of its own within `found_distance_m` of it in
//      that keyframe. A point that `min_expected_views` keyframes should have seen and none saw
//      is gone (or hidden for good behind something new) and is removed;
//   3. the session is merged into what remains (map_merge.h): what is new is added, duplicates
//      fused, the kernel and the vocabulary learned again.
// Points the session never came near are kept: no view, no evidence.

#include <optional>

#include "core/map/map.h"
#include "mapping/map_merge.h"

namespace visloc::mapping {

struct UpdateOptions {
  MergeOptions merge;
  int min_expected_views = 3;
  double found_distance_m = 0.05;
  double max_depth_m = 6.0;
  double max_view_angle_deg = 30.0;
  double image_margin_px = 8.0;
  void Check() const;  // The merge options too.
};

struct UpdateStats {
  int checked_points = 0;  // Map points that enough session keyframes should have seen.
  int removed_points = 0;  // Of those, seen by none.
  MergeStats merge;        // Registration, then the merge of the session into what remains.
};

// Throws InputError as MergeMaps does when the session does not overlap the map.
Map UpdateMap(const Map& map, const Map& session, const UpdateOptions& options, UpdateStats* stats,
              const std::optional<Rigid3d>& map_from_session_guess = std::nullopt);

}  // namespace visloc::mapping
