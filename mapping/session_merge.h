#pragma once
// A new stereo session added to an existing map (`visloc map extend`) or bringing it up to date
// (`visloc map update`), as one library call that takes frames: the CLI reads them from a
// dataset folder, a server could take them from a robot's stream.
//
//   1. the session's camera must be the map's (a map grows with sessions of its own camera);
//   2. its left images are localized in the map as a robot's would be (session_registration.h):
//      a session that never sees the mapped place is refused here, before minutes of mapping;
//   3. the session is mapped on its own with the map's detector (StereoSource::BuildMap);
//   4. the images placed both ways place the session in the map (FitMapFromSession);
//   5. merged (map_merge.h), or for an update first cleared of what is gone (map_update.h).
// Every refusal for want of overlap names the session: "the session NAME does not overlap the
// map: <evidence>". The result carries the map's new lineage; writing it is the caller's.

#include <functional>
#include <string>

#include "core/map/map.h"
#include "mapping/map_update.h"
#include "mapping/session_registration.h"
#include "mapping/stereo_source.h"

namespace visloc::mapping {

enum class SessionMergeKind { kExtend, kUpdate };

struct SessionMergeOptions {
  SessionRegistrationOptions registration;
  // For an update; an extension uses `update.merge` alone.
  UpdateOptions update;
  int threads = 1;  // The session's mapping (MapBuilderOptions::threads; 0: every core).
  void Check() const;  // Checks the nested options too.
};

struct SessionMergeStats {
  int map_points = 0;                     // The existing map's, before.
  SessionRegistrationStats registration;  // How the session's images localized in the map.
  Rigid3d map_from_session;               // The placement the merge started from.
  MapBuildStats session_build;            // The session's own mapping.
  // An update's point check and, for both kinds, the merge (update.merge).
  UpdateStats update;
};

// Where a long call is: `stage` is kLocalizing (done of total images localized in the map) or
// kMapping (done of total frames mapped, `status` the builder's).
struct SessionMergeProgress {
  enum class Stage { kLocalizing, kMapping } stage = Stage::kLocalizing;
  int done = 0;
  int total = 0;
  std::string status;
};

// The map with the session merged in, in `existing`'s frame. Throws InputError for another
// camera, a session that does not overlap the map (the evidence named), unreadable frames or a
// session that does not map.
Map MergeSession(const Map& existing, const StereoSource& session, SessionMergeKind kind,
                 const SessionMergeOptions& options, SessionMergeStats* stats,
                 const std::function<void(const SessionMergeProgress&)>& progress = nullptr);

}  // namespace visloc::mapping
