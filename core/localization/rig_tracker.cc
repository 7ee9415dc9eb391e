#include "core/localization/rig_tracker.h"

#include <algorithm>

#include "core/localization/relocalizer.h"
#include "core/util/check.h"
#include "core/util/timer.h"

namespace visloc {

RigTracker::RigTracker(std::vector<const PoseTracker*> trackers, std::vector<Rigid3d> cam_from_ref,
                       WorkerPool* workers, int threads)
    : trackers_(std::move(trackers)),
      cam_from_ref_(std::move(cam_from_ref)),
      workers_(workers),
      threads_(threads) {
  VISLOC_CHECK(workers_ != nullptr && threads_ >= 1, "rig threads ", threads_);
  VISLOC_CHECK(!trackers_.empty() && trackers_.size() == cam_from_ref_.size(),
               "rig: ", trackers_.size(), " trackers for ", cam_from_ref_.size(), " placements");
}

std::vector<PoseObservation> RigTracker::Observations(size_t camera, const QueryFrame& frame,
                                                      const CameraMatches& matches) const {
  std::vector<PoseObservation> observations =
      trackers_[camera]->Observations(matches.map_points, frame, matches.matches);
  // A normalized error of e is e * fx_c pixels in camera c: weighed in the reference's focal.
  const double to_reference = trackers_[camera]->camera().fx() / reference().camera().fx();
  if (to_reference != 1.0) {
    for (PoseObservation& o : observations) o.pixel_scale *= to_reference;
  }
  return observations;
}

void RigTracker::set_threads(int threads) {
  VISLOC_CHECK(threads >= 1, "rig threads ", threads);
  threads_ = threads;
}

void RigTracker::ForEachCamera(const std::function<void(size_t)>& fn) const {
  workers_->ForEach(static_cast<int>(trackers_.size()), threads_,
                    [&](int c) { fn(static_cast<size_t>(c)); });
}

int RigTracker::CoarsePointsPerCamera(const std::vector<const QueryFrame*>& frames) const {
  const PoseTrackerOptions& options = reference().options();
  if (options.coarse_points == 0) return 0;
  const int seeing = static_cast<int>(std::count_if(
      frames.begin(), frames.end(), [](const QueryFrame* f) { return f && f->size() > 0; }));
  return std::max(options.rig_min_coarse_points, options.coarse_points / std::max(1, seeing));
}

RigTracker::CameraPrediction RigTracker::PredictCamera(size_t camera,
                                                       const Rigid3d& prior_ref_from_map) const {
  const PoseTracker& tracker = *trackers_[camera];
  const Rigid3d cam_from_map = cam_from_ref_[camera] * prior_ref_from_map;
  CameraPrediction prediction;
  prediction.points = tracker.PredictPoints(cam_from_map, &prediction.fix);
  Timer timer;
  prediction.map_points = tracker.map().Points(prediction.points);
  prediction.fix.times.predict_ms += timer.ElapsedMs();
  timer.Restart();
  prediction.projected =
      ProjectPoints(prediction.map_points, tracker.camera(), cam_from_map, prediction.points);
  prediction.fix.times.project_ms += timer.ElapsedMs();
  return prediction;
}

namespace {

bool SamePose(const Rigid3d& a, const Rigid3d& b) {
  return a.rotation.coeffs() == b.rotation.coeffs() && a.translation == b.translation;
}

}  // namespace

PoseFix RigTracker::Track(const std::vector<const QueryFrame*>& frames,
                          const Rigid3d& prior_ref_from_map,
                          std::optional<Prediction> prediction) const {
  VISLOC_CHECK(frames.size() == trackers_.size(), "rig of ", trackers_.size(), " cameras given ",
               frames.size(), " frames");
  if (prediction && (prediction->cameras.size() != trackers_.size() ||
                     !SamePose(prediction->prior_ref_from_map, prior_ref_from_map))) {
    prediction.reset();  // Made for another prior (a held fix's, say).
  }
  PoseFix fix;
  fix.cameras.resize(trackers_.size());
  std::vector<CameraMatches> per_camera(trackers_.size());
  std::vector<std::vector<ProjectedPoint>> projected(trackers_.size());
  RigObservations rig;
  rig.cam_from_ref = cam_from_ref_;
  rig.per_camera.resize(trackers_.size());
  const int coarse_points = CoarsePointsPerCamera(frames);
  // Each camera's prediction (unless made already) and wide search, the cameras side by side;
  // their counts and times (summed: CPU time, as the steps of one camera are) merged after.
  std::vector<PoseFix> camera_fixes(trackers_.size());
  std::vector<char> camera_subsampled(trackers_.size(), 0);
  ForEachCamera([&](size_t c) {
    if (frames[c] == nullptr || frames[c]->size() == 0) return;
    const PoseTracker& tracker = *trackers_[c];
    CameraPrediction predicted =
        prediction ? std::move(prediction->cameras[c]) : PredictCamera(c, prior_ref_from_map);
    CameraMatches& camera = per_camera[c];
    camera.points = std::move(predicted.points);
    camera.map_points = std::move(predicted.map_points);
    projected[c] = std::move(predicted.projected);
    PoseFix& camera_fix = camera_fixes[c];
    camera_fix = std::move(predicted.fix);
    Timer timer;
    std::vector<ProjectedPoint> subset;
    const std::vector<ProjectedPoint>& coarse =
        tracker.CoarseSubset(projected[c], coarse_points, &subset);
    camera_subsampled[c] = coarse.size() < projected[c].size();
    camera_fix.times.project_ms += timer.ElapsedMs();
    timer.Restart();
    camera.matches = MatchProjected(camera.map_points, coarse, *frames[c],
                                    tracker.options().search_radius_px, tracker.options().matching);
    camera_fix.times.match_ms += timer.ElapsedMs();
    rig.per_camera[c] = Observations(c, *frames[c], camera);
  });
  bool subsampled = false;
  for (size_t c = 0; c < trackers_.size(); ++c) {
    if (frames[c] != nullptr) fix.cameras[c].features = static_cast<int>(frames[c]->size());
    subsampled |= camera_subsampled[c] != 0;
    fix.predicted += camera_fixes[c].predicted;
    fix.cameras[c].predicted = camera_fixes[c].predicted;
    fix.times.predict_ms += camera_fixes[c].times.predict_ms;
    fix.times.project_ms += camera_fixes[c].times.project_ms;
    fix.times.match_ms += camera_fixes[c].times.match_ms;
  }
  // One refinement pass: RefineAround re-matches around this pose and refines twice anyway.
  PnpRansacOptions ransac_options = reference().options().ransac;
  ransac_options.refinement_passes = 1;
  Timer timer;
  RigPnpResult ransac = SolveRigPnpRansac(rig, ransac_options);
  fix.ransac_iterations += ransac.stats.iterations;
  fix.times.pose_ms += timer.ElapsedMs();
  if (!ransac.success && subsampled) {
    // As PoseTracker::Track: RANSAC failed on the subsets, so every projected point is tried.
    timer.Restart();
    ForEachCamera([&](size_t c) {
      if (projected[c].empty()) return;
      const PoseTracker& tracker = *trackers_[c];
      per_camera[c].matches =
          MatchProjected(per_camera[c].map_points, projected[c], *frames[c],
                         tracker.options().search_radius_px, tracker.options().matching);
      rig.per_camera[c] = Observations(c, *frames[c], per_camera[c]);
    });
    fix.times.match_ms += timer.ElapsedMs();
    timer.Restart();
    ransac = SolveRigPnpRansac(rig, ransac_options);
    fix.ransac_iterations += ransac.stats.iterations;
    fix.times.pose_ms += timer.ElapsedMs();
  }
  fix.putatives = static_cast<int>(rig.size());
  if (!ransac.success) return fix;
  RefineAround(frames, &per_camera, ransac.ref_from_world, &fix);
  return fix;
}

PoseFix RigTracker::Polish(const std::vector<const QueryFrame*>& frames,
                           const Rigid3d& ref_from_map) const {
  VISLOC_CHECK(frames.size() == trackers_.size(), "rig of ", trackers_.size(), " cameras given ",
               frames.size(), " frames");
  PoseFix fix;
  fix.cameras.resize(trackers_.size());
  std::vector<CameraMatches> per_camera(trackers_.size());
  for (size_t c = 0; c < trackers_.size(); ++c) {
    if (frames[c] == nullptr || frames[c]->size() == 0) continue;
    fix.cameras[c].features = static_cast<int>(frames[c]->size());
    PoseFix camera_fix;
    per_camera[c].points =
        trackers_[c]->PredictPoints(cam_from_ref_[c] * ref_from_map, &camera_fix);
    per_camera[c].map_points = trackers_[c]->map().Points(per_camera[c].points);
    fix.predicted += camera_fix.predicted;
    fix.cameras[c].predicted = camera_fix.predicted;
    fix.times.predict_ms += camera_fix.times.predict_ms;
  }
  RefineAround(frames, &per_camera, ref_from_map, &fix);
  return fix;
}

void RigTracker::RefineAround(const std::vector<const QueryFrame*>& frames,
                              std::vector<CameraMatches>* per_camera, const Rigid3d& ref_from_map,
                              PoseFix* fix) const {
  RigObservations rig;
  rig.cam_from_ref = cam_from_ref_;
  rig.per_camera.resize(trackers_.size());
  std::vector<PoseStepTimes> camera_times(trackers_.size());
  ForEachCamera([&](size_t c) {
    CameraMatches& camera = (*per_camera)[c];
    if (frames[c] == nullptr || camera.points.empty()) return;
    const PoseTracker& tracker = *trackers_[c];
    Timer timer;
    const std::vector<ProjectedPoint> projected = ProjectPoints(
        camera.map_points, tracker.camera(), cam_from_ref_[c] * ref_from_map, camera.points);
    camera_times[c].project_ms = timer.ElapsedMs();
    timer.Restart();
    camera.matches = MatchProjected(camera.map_points, projected, *frames[c],
                                    tracker.options().refine_radius_px, tracker.options().matching);
    camera_times[c].match_ms = timer.ElapsedMs();
    rig.per_camera[c] = Observations(c, *frames[c], camera);
  });
  for (size_t c = 0; c < trackers_.size(); ++c) {
    fix->times.project_ms += camera_times[c].project_ms;
    fix->times.match_ms += camera_times[c].match_ms;
    fix->cameras[c].putatives = static_cast<int>((*per_camera)[c].matches.size());
  }
  Timer timer;
  RigPnpResult refined = RefineRigPoseOnInliers(ref_from_map, rig, reference().options().ransac);
  if (refined.success && DropChanceCameras(refined, &rig, per_camera)) {
    refined = RefineRigPoseOnInliers(refined.ref_from_world, rig, reference().options().ransac);
  }
  fix->times.pose_ms += timer.ElapsedMs();
  fix->putatives = static_cast<int>(rig.size());
  fix->success = refined.success;
  if (!refined.success) {
    fix->inliers = 0;
    fix->inlier_ratio = 0.0;
    return;
  }
  fix->cam_from_map = refined.ref_from_world;
  fix->inliers = refined.stats.inliers;
  fix->inlier_ratio = refined.stats.inlier_ratio;
  fix->reproj_rmse_px = refined.stats.refine.final_rmse_px;
  timer.Restart();
  SetCovariances(frames, *per_camera, rig, refined, fix);
  fix->times.pose_ms += timer.ElapsedMs();
  // The coverage grid over all images: cells of several cameras add up (two cameras each
  // covering half their image constrain the pose as well as one covering all of it).
  int cells = 0;
  for (size_t c = 0; c < trackers_.size(); ++c) {
    fix->cameras[c].inliers = refined.camera_inliers[c];
    if (frames[c] == nullptr || refined.inlier_masks[c].empty()) continue;
    cells +=
        trackers_[c]->InlierCells(*frames[c], (*per_camera)[c].matches, refined.inlier_masks[c]);
  }
  fix->inlier_cells = std::min(cells, PoseFix::kCoverageCols * PoseFix::kCoverageRows);
}

bool RigTracker::DropChanceCameras(const RigPnpResult& refined, RigObservations* rig,
                                   std::vector<CameraMatches>* per_camera) const {
  bool dropped = false;
  for (size_t c = 0; c < trackers_.size(); ++c) {
    const int inliers = refined.camera_inliers[c];
    if (inliers == 0) continue;
    const PoseTrackerOptions& options = trackers_[c]->options();
    const double significance =
        ChanceInliersNegLog10(static_cast<int>(rig->per_camera[c].size()), inliers,
                              options.ransac.max_error_px, options.refine_radius_px);
    if (significance >= options.rig_camera_min_significance) continue;
    rig->per_camera[c].clear();
    (*per_camera)[c].matches.clear();
    dropped = true;
  }
  return dropped;
}

void RigTracker::SetCovariances(const std::vector<const QueryFrame*>& frames,
                                const std::vector<CameraMatches>& per_camera,
                                const RigObservations& rig, const RigPnpResult& refined,
                                PoseFix* fix) const {
  const PoseTrackerOptions& options = reference().options();
  // As PoseTracker: the refinement's covariance scaled by the measured residual (floored).
  const double sigma_px = std::max(0.3, fix->reproj_rmse_px);
  const double unit = options.ransac.refine.pixel_sigma_px;
  fix->covariance = refined.covariance * (sigma_px * sigma_px) / (unit * unit);
  const double unit_normalized = unit / options.ransac.refine.focal_px;
  const Eigen::Matrix<double, 6, 6> inverse_information =
      refined.covariance / (unit_normalized * unit_normalized);
  // The map's share at the inliers' median depth, each in its own camera.
  std::vector<double> depths;
  // The points' spread over all cameras, by the reference's perturbation (Ad^T S Ad, as the
  // refinement's information: pose_refinement.h's PoseAdjoint).
  Eigen::Matrix<double, 6, 6> spread = Eigen::Matrix<double, 6, 6>::Zero();
  bool points_known = options.point_error_gain > 0;
  const Rigid3d& ref_from_map = refined.ref_from_world;
  for (size_t c = 0; c < trackers_.size(); ++c) {
    if (frames[c] == nullptr || rig.per_camera[c].empty()) continue;
    const Rigid3d cam_from_map = cam_from_ref_[c] * ref_from_map;
    const std::vector<char>& inliers = refined.inlier_masks[c];
    for (size_t m = 0; m < rig.per_camera[c].size(); ++m) {
      if (inliers[m]) depths.push_back((cam_from_map * rig.per_camera[c][m].point_in_world).z());
    }
    if (points_known) {
      const PointSpread camera =
          trackers_[c]->PointSpreadOf(per_camera[c].map_points, per_camera[c].matches,
                                      rig.per_camera[c], inliers, cam_from_map);
      points_known = !camera.unknown;
      const Eigen::Matrix<double, 6, 6> adjoint = PoseAdjoint(cam_from_ref_[c]);
      spread += camera.to_all * adjoint.transpose() * camera.Matrix() * adjoint;
    }
  }
  std::nth_element(depths.begin(), depths.begin() + depths.size() / 2, depths.end());
  const double median_depth_m = depths.empty() ? 0.0 : depths[depths.size() / 2];
  const Eigen::Matrix<double, 6, 6> map_and_rig =
      reference().MapAndRigCovariance(median_depth_m, ref_from_map.Inverse().translation.norm());
  Eigen::Matrix<double, 6, 6> from_points = Eigen::Matrix<double, 6, 6>::Zero();
  if (points_known) {
    from_points = options.point_error_gain * inverse_information * spread * inverse_information;
  }
  fix->systematic_covariance = map_and_rig + from_points;
  const double rest_variance = (fix->covariance + map_and_rig).topLeftCorner<3, 3>().trace();
  fix->point_variance_ratio =
      rest_variance > 0 ? from_points.topLeftCorner<3, 3>().trace() / rest_variance : 0.0;
}

}  // namespace visloc
