#include "mapping/session_registration.h"

#include <cmath>
#include <map>
#include <memory>

#include "core/geometry/align.h"
#include "core/localization/localizer.h"
#include "core/util/check.h"
#include "core/util/strings.h"
#include "core/util/timer.h"

namespace visloc::mapping {
namespace {

// An image placed both ways: by the session's mapping and by localization in the map.
struct PosePair {
  Rigid3d session_from_cam;
  Rigid3d map_from_cam;
};

bool Agrees(const Rigid3d& map_from_session, const PosePair& pair,
            const SessionRegistrationOptions& options) {
  return ApproxEqual(map_from_session * pair.session_from_cam, pair.map_from_cam,
                     options.agree_distance_m, options.agree_angle_deg);
}

std::vector<int> Agreeing(const Rigid3d& map_from_session, const std::vector<PosePair>& pairs,
                          const SessionRegistrationOptions& options) {
  std::vector<int> agreeing;
  for (size_t i = 0; i < pairs.size(); ++i) {
    if (Agrees(map_from_session, pairs[i], options)) agreeing.push_back(static_cast<int>(i));
  }
  return agreeing;
}

// Least squares over the agreeing images: each contributes its camera centre and the points 1 m
// along its three axes, so that orientation counts beside position, and a single image or a
// straight path still determines the rotation.
Rigid3d FitPoses(const std::vector<PosePair>& pairs, const std::vector<int>& chosen) {
  std::vector<Eigen::Vector3d> in_session, in_map;
  for (int i : chosen) {
    for (int axis = -1; axis < 3; ++axis) {
      const Eigen::Vector3d in_cam =
          axis < 0 ? Eigen::Vector3d::Zero() : Eigen::Vector3d::Unit(axis).eval();
      in_session.push_back(pairs[i].session_from_cam * in_cam);
      in_map.push_back(pairs[i].map_from_cam * in_cam);
    }
  }
  return AlignRigid(in_session, in_map);
}

bool Strong(const LocalizationResult& result, int min_inliers) {
  const bool visual =
      result.source == PoseSource::kTracking || result.source == PoseSource::kRelocalization;
  return result.has_pose && visual && result.stats.inliers >= min_inliers &&
         (result.status == TrackingStatus::kTracking ||
          result.status == TrackingStatus::kRelocalized);
}

}  // namespace

void SessionRegistrationOptions::Check() const {
  if (min_fix_inliers < 3) throw CheckError("a fix needs at least 3 inliers");
  if (!(agree_distance_m > 0) || !(agree_angle_deg > 0))
    throw CheckError("the agreement bounds must be positive");
  if (min_agreeing_frames < 1) throw CheckError("at least one image must localize");
}

Rigid3d FitMapFromSession(const Trajectory& session_from_cam, const Trajectory& map_from_cam,
                          const SessionRegistrationOptions& options,
                          SessionRegistrationStats* stats) {
  options.Check();
  std::map<int64_t, Rigid3d> fix_at;
  for (const StampedPose& p : map_from_cam) fix_at[p.timestamp_ns] = p.pose;
  std::vector<PosePair> pairs;
  for (const StampedPose& p : session_from_cam) {
    const auto fix = fix_at.find(p.timestamp_ns);
    if (fix != fix_at.end()) pairs.push_back({p.pose, fix->second});
  }
  stats->paired_frames = static_cast<int>(pairs.size());

  // Every image's own candidate, scored by how many others agree with it. A session's images
  // number in the thousands at most; stride the candidates beyond a few hundred.
  std::vector<int> best;
  Rigid3d map_from_session;
  const size_t stride = 1 + pairs.size() / 500;
  for (size_t i = 0; i < pairs.size(); i += stride) {
    const Rigid3d candidate = pairs[i].map_from_cam * pairs[i].session_from_cam.Inverse();
    std::vector<int> agreeing = Agreeing(candidate, pairs, options);
    if (agreeing.size() > best.size()) {
      best = std::move(agreeing);
      map_from_session = candidate;
    }
  }
  for (int refit = 0; refit < 2 && !best.empty(); ++refit) {
    map_from_session = FitPoses(pairs, best);
    best = Agreeing(map_from_session, pairs, options);
  }
  stats->agreeing_frames = static_cast<int>(best.size());
  if (stats->agreeing_frames < options.min_agreeing_frames) {
    throw InputError(StrCat(stats->agreeing_frames, " of the ", stats->paired_frames,
                            " images that localized in the map (and that the session's own "
                            "mapping placed) agree on one placement of the session; ",
                            options.min_agreeing_frames, " are needed"));
  }
  double sum_sq = 0.0;
  for (int i : best) {
    sum_sq += ((map_from_session * pairs[i].session_from_cam).translation -
               pairs[i].map_from_cam.translation)
                  .squaredNorm();
  }
  stats->position_rmse_m = std::sqrt(sum_sq / best.size());
  return map_from_session;
}

Trajectory LocalizeSessionImages(const Map& map, const StereoSource& session,
                                 const SessionRegistrationOptions& options,
                                 SessionRegistrationStats* stats,
                                 const std::function<void(int, int)>& progress) {
  options.Check();
  *stats = SessionRegistrationStats{};
  Timer timer;
  Localizer localizer(std::make_shared<const LocalizationMap>(map), session.left_camera(),
                      options.localizer);
  Trajectory localized;
  const int total = session.size();
  for (int i = 0; i < total; ++i) {
    FrameInput input;
    input.timestamp_ns = session.TimestampNs(i);
    input.image = session.ReadLeft(i);
    const LocalizationResult result = localizer.Process(input);
    ++stats->frames;
    if (Strong(result, options.min_fix_inliers)) {
      localized.push_back({input.timestamp_ns, result.map_from_cam});
    }
    if (progress) progress(stats->frames, total);
  }
  stats->localized_frames = static_cast<int>(localized.size());
  stats->localize_ms = timer.ElapsedMs();
  if (stats->localized_frames < options.min_agreeing_frames) {
    throw InputError(StrCat(stats->localized_frames, " of the session's ", stats->frames,
                            " images localized in the map (relocalization found no verified "
                            "place for the others); ",
                            options.min_agreeing_frames,
                            " are needed. A session that never sees the mapped place is not "
                            "added to it"));
  }
  return localized;
}

}  // namespace visloc::mapping
