#include "mapping/session_merge.h"

#include <ctime>

#include "core/util/check.h"
#include "core/util/strings.h"
#include "core/util/version.h"

namespace visloc::mapping {

void SessionMergeOptions::Check() const {
  registration.Check();
  update.Check();
  VISLOC_CHECK(threads >= 0, "session mapping threads: ", threads, " (0: every core)");
}

namespace {

const char* VerbOf(SessionMergeKind kind) {
  return kind == SessionMergeKind::kExtend ? "extend" : "update";
}

// Before minutes of work: a map grows with sessions of its own camera.
void RequireMapCamera(const Map& existing, const StereoSource& session) {
  if (!SameCamera(existing.camera, session.left_camera())) {
    throw InputError(StrCat("the session ", session.name(), "'s left camera (",
                            ToString(session.left_camera()), ") is not the map's (",
                            ToString(existing.camera),
                            "): a map grows with sessions of its own camera"));
  }
}

// Runs `step`; an InputError from it (no overlap, with the evidence) names the session.
template <typename Step>
auto NamingTheSession(const StereoSource& session, Step&& step) -> decltype(step()) {
  try {
    return step();
  } catch (const InputError& e) {
    throw InputError(
        StrCat("the session ", session.name(), " does not overlap the map: ", e.what()));
  }
}

// The session mapped on its own, with the existing map's detector, as `map build` would, and
// with the rig's disparity correction the map records (RequireMapCamera: the same rig), so a
// session too short to estimate it maps as metrically as the map did; `frame_trajectory`:
// where its mapping placed each image.
Map MapSession(const Map& existing, const StereoSource& session, SessionMergeKind kind, int threads,
               MapBuildStats* stats, Trajectory* frame_trajectory,
               const std::function<void(const SessionMergeProgress&)>& progress) {
  MapBuilderOptions builder;
  builder.features = DefaultFeatureSettings(existing.features.kind);
  builder.threads = threads;
  if (existing.metadata.disparity_correction) {
    builder.disparity_calibration.known = existing.metadata.disparity_correction;
    builder.disparity_calibration.enabled = false;
  }
  const MapMetadata metadata{"session", static_cast<int64_t>(std::time(nullptr)), session.origin(),
                             StrCat("visloc ", VislocVersion(), " map ", VerbOf(kind)), ""};
  return session.BuildMap(
      builder, metadata, stats, frame_trajectory,
      [&](int done, int total, const std::string& status) {
        if (progress) progress({SessionMergeProgress::Stage::kMapping, done, total, status});
      });
}

}  // namespace

Map MergeSession(const Map& existing, const StereoSource& session, SessionMergeKind kind,
                 const SessionMergeOptions& options, SessionMergeStats* stats,
                 const std::function<void(const SessionMergeProgress&)>& progress) {
  options.Check();
  *stats = SessionMergeStats{};
  stats->map_points = static_cast<int>(existing.points.size());
  RequireMapCamera(existing, session);
  const Trajectory map_from_cam = NamingTheSession(session, [&] {
    return LocalizeSessionImages(
        existing, session, options.registration, &stats->registration, [&](int done, int total) {
          if (progress) progress({SessionMergeProgress::Stage::kLocalizing, done, total, ""});
        });
  });
  Trajectory session_from_cam;
  const Map session_map = MapSession(existing, session, kind, options.threads,
                                     &stats->session_build, &session_from_cam, progress);
  stats->map_from_session = NamingTheSession(session, [&] {
    return FitMapFromSession(session_from_cam, map_from_cam, options.registration,
                             &stats->registration);
  });
  return NamingTheSession(session, [&] {
    if (kind == SessionMergeKind::kUpdate) {
      return UpdateMap(existing, session_map, options.update, &stats->update,
                       stats->map_from_session);
    }
    Map extended = MergeMaps(existing, session_map, options.update.merge, &stats->update.merge,
                             stats->map_from_session);
    extended.metadata.lineage = MergedLineage(existing.metadata, session_map.metadata, "extend");
    return extended;
  });
}

}  // namespace visloc::mapping
