#pragma once
// A new session found in an existing map the way a robot is found (`visloc map extend`, `map
// update`): the session's left images go through the map's localization engine in order, as a
// server session runs them (relocalization by appearance with geometric verification first,
// then visibility-guided tracking); that needs no map of the session, so a session that never
// localizes is refused before it is mapped. Each image with a strong visual fix that the
// session's own stereo mapping also placed (its frame trajectory, which follows the mapper's bundle
// adjustments) gives one candidate for the session's frame in the map:
//
//   map_from_session = map_from_cam (localized) * session_from_cam^-1 (the session's mapping).
//
// Candidates are tried one by one, and the one most of the others agree with (camera centre and
// orientation) wins; a least-squares fit over the agreeing images gives the guess that the merge
// then refines with the points (map_merge.h). Stereo maps share metric scale: no scale. Images
// that localized wrongly (a look-alike place, the edge of the map) disagree and are left out; a
// session that never localizes, or whose fixes agree on nothing, is refused. Images, not only
// keyframes: a camera that stood still has one keyframe and many images.

#include <functional>
#include <string>

#include "core/geometry/trajectory.h"
#include "core/localization/localizer_options.h"
#include "core/map/map.h"
#include "mapping/stereo_source.h"

namespace visloc::mapping {

struct SessionRegistrationOptions {
  LocalizerOptions localizer;
  int min_fix_inliers = 40;        // A tracking or relocalized fix counts from this many inliers.
  double agree_distance_m = 0.05;  // Camera centres of an agreeing keyframe, after the transform.
  double agree_angle_deg = 2.0;    // Their orientations.
  int min_agreeing_frames = 3;     // Fewer: the session is refused.
  void Check() const;              // Throws CheckError naming the first bad value.
};

struct SessionRegistrationStats {
  int frames = 0;                // Session images run through the localization engine.
  int localized_frames = 0;      // Of those, with a strong visual fix.
  int paired_frames = 0;         // Of those, placed by the session's mapping too.
  int agreeing_frames = 0;       // Of those, agreeing with the chosen map_from_session.
  double position_rmse_m = 0.0;  // Agreeing images' camera centres after the fit.
  double localize_ms = 0.0;
};

// The session's frame in the map from images placed both ways: `session_from_cam` by the
// session's mapping, `map_from_cam` by localization in the map (strong fixes only); paired by
// exact time. Throws InputError naming the evidence when fewer than `min_agreeing_frames` agree.
Rigid3d FitMapFromSession(const Trajectory& session_from_cam, const Trajectory& map_from_cam,
                          const SessionRegistrationOptions& options,
                          SessionRegistrationStats* stats);

// Localizes every left image of `session` in `map` (which needs its visibility kernel and
// appearance index), in order: the map_from_cam of the images with a strong fix, for
// FitMapFromSession. It needs no map of the session, so a session that never sees the mapped
// place is refused before it is mapped: InputError when fewer than `min_agreeing_frames` images
// localize, and for unreadable images. `progress(done, total)` per image.
Trajectory LocalizeSessionImages(const Map& map, const StereoSource& session,
                                 const SessionRegistrationOptions& options,
                                 SessionRegistrationStats* stats,
                                 const std::function<void(int, int)>& progress = nullptr);

}  // namespace visloc::mapping
