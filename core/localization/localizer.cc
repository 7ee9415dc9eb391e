#include "core/localization/localizer.h"

#include <cmath>
#include <utility>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include "core/geometry/trajectory.h"
#include "core/util/check.h"
#include "core/util/parallel.h"
#include "core/util/timer.h"

namespace visloc {

const char* PoseSourceName(PoseSource source) {
  switch (source) {
    case PoseSource::kNone:
      return "none";
    case PoseSource::kTracking:
      return "tracking";
    case PoseSource::kRelocalization:
      return "relocalization";
    case PoseSource::kMotion:
      return "motion";
  }
  return "?";
}

const char* RelocalizationKindName(RelocalizationReport::Kind kind) {
  switch (kind) {
    case RelocalizationReport::Kind::kNone:
      return "none";
    case RelocalizationReport::Kind::kLocal:
      return "local";
    case RelocalizationReport::Kind::kGlobal:
      return "global";
  }
  return "?";
}

Eigen::Matrix3d LocalizationResult::PositionCovarianceInMap() const {
  if (!has_pose) return Eigen::Matrix3d::Zero();
  const Eigen::Matrix3d map_from_cam_rotation = map_from_cam.rotation.toRotationMatrix();
  return map_from_cam_rotation * covariance.topLeftCorner<3, 3>() *
         map_from_cam_rotation.transpose();
}

double LocalizationResult::PositionSigmaPerAxisM() const {
  return has_pose ? std::sqrt(std::max(0.0, covariance.topLeftCorner<3, 3>().trace() / 3.0)) : 0.0;
}

void LocalizerOptions::Check() const {
  tracker.Check();
  relocalization.Check();
  VISLOC_CHECK(min_limited_inliers >= tracker.ransac.min_inliers &&
                   min_tracking_inliers >= min_limited_inliers,
               "inlier thresholds: ransac ", tracker.ransac.min_inliers, ", limited ",
               min_limited_inliers, ", tracking ", min_tracking_inliers);
  VISLOC_CHECK(max_tracking_point_variance_ratio >= 0, "max_tracking_point_variance_ratio ",
               max_tracking_point_variance_ratio);
  VISLOC_CHECK(max_jump_m > 0 && max_jump_deg > 0 && max_innovation_chi2 > 0, "jump gate ",
               max_jump_m, " m ", max_jump_deg, " deg, innovation chi2 ", max_innovation_chi2);
  VISLOC_CHECK(motion.plane_sigma_m >= 0 && motion.max_bridge_s >= 0, "motion options");
  VISLOC_CHECK(rig_threads >= 1 && max_rig_skew_ns >= 0, "rig threads ", rig_threads, ", skew ",
               max_rig_skew_ns, " ns");
  VISLOC_CHECK(max_query_features >= 0 && max_relocalization_features >= 0,
               "keypoint counts: query ", max_query_features, ", relocalization ",
               max_relocalization_features);
  VISLOC_CHECK(resample_ratio >= 1.0, "query resample ratio ", resample_ratio);
}

std::optional<std::pair<Eigen::Vector3d, double>> FitKeyframePlane(const LocalizationMap& map,
                                                                   const MotionOptions& options) {
  const auto& centers = map.keyframe_centers();
  if (static_cast<int>(centers.size()) < options.plane_min_keyframes) return std::nullopt;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& c : centers) mean += c;
  mean /= static_cast<double>(centers.size());
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (const auto& c : centers) scatter += (c - mean) * (c - mean).transpose();
  scatter /= static_cast<double>(centers.size());
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(scatter);
  const Eigen::Vector3d sigmas = solver.eigenvalues().cwiseMax(0.0).cwiseSqrt();  // Ascending.
  // Spread in two directions and flat compared with that.
  if (sigmas(1) < options.plane_min_spread_m || sigmas(0) > options.plane_max_flatness * sigmas(1))
    return std::nullopt;
  Eigen::Vector3d normal = solver.eigenvectors().col(0);
  // Point the normal up: against the first keyframe camera's y axis (down in OpenCV).
  const Eigen::Vector3d down =
      map.map().keyframes[0].map_from_cam.rotation * Eigen::Vector3d::UnitY();
  if (normal.dot(down) > 0) normal = -normal;
  return std::make_pair(normal, normal.dot(mean));
}

namespace {

// `rig`, once CameraRig::Check has passed it.
const CameraRig& Checked(const CameraRig& rig) {
  rig.Check();
  return rig;
}

// A one-camera rig: `camera` at `body_from_cam` when given (its gyro then in that body frame).
CameraRig SingleCameraRig(const Camera& camera, const std::optional<Rigid3d>& body_from_cam) {
  CameraRig rig;
  rig.cameras = {camera};
  rig.body_from_cam = {body_from_cam.value_or(Rigid3d())};
  rig.body_is_gyro_frame = body_from_cam.has_value();
  return rig;
}

}  // namespace

Localizer::Localizer(std::shared_ptr<const LocalizationMap> map, const Camera& camera,
                     const LocalizerOptions& options, const std::optional<Rigid3d>& body_from_cam)
    : Localizer(std::move(map), SingleCameraRig(camera, body_from_cam), options) {}

Localizer::Localizer(std::shared_ptr<const LocalizationMap> map, const CameraRig& rig,
                     const LocalizerOptions& options)
    : map_(std::move(map)),
      rig_(Checked(rig)),
      camera_(rig.cameras[0]),
      pipeline_(map_, rig_, options),
      options_(reference().options()) {
  if (rig_.body_is_gyro_frame) {
    cam_from_body_rotation_ = rig_.body_from_cam[0].rotation.toRotationMatrix().transpose();
  }
  if (options_.motion.plane_sigma_m > 0) {
    plane_ = FitKeyframePlane(*map_, options_.motion);
    if (!plane_) {
      throw InputError("planar motion needs a map whose keyframes span a plane");
    }
  }
}

void Localizer::SetRigThreads(int threads) {
  VISLOC_CHECK(threads >= 1, "rig threads ", threads);
  options_.rig_threads = threads;
  pipeline_.SetThreads(threads);
}

void Localizer::ForEachOnRigThreads(int n, const std::function<void(int i)>& fn) const {
  pipeline_.ForEachClaimed(n, fn);
}

std::vector<const QueryFrame*> Localizer::RigFrames(const QueryFrame& reference) const {
  std::vector<const QueryFrame*> frames = {&reference};
  for (const std::optional<QueryFrame>& frame : rig_frames_) {
    frames.push_back(frame ? &*frame : nullptr);
  }
  frames.resize(pipeline_.size(), nullptr);
  return frames;
}

PoseFix Localizer::TrackFrame(const QueryFrame& frame, const Rigid3d& prior_cam_from_map) {
  if (!rig()) return reference().tracker().Track(frame, prior_cam_from_map);
  return pipeline_.tracker()->Track(RigFrames(frame), prior_cam_from_map,
                                    std::exchange(rig_prediction_, std::nullopt));
}

QueryFrame Localizer::ExtractRig(const FrameInput& input, FrameStats* stats,
                                 const std::optional<Rigid3d>& prior_cam_from_map) {
  const size_t n = pipeline_.size();
  std::vector<std::optional<QueryFrame>> frames(n);
  std::vector<ExtractStats> extract(n);
  std::vector<double> undistort_ms(n, 0.0);
  const auto image_of = [&](size_t c) -> const cv::Mat& {
    return c == 0 ? input.image : input.rig_images[c - 1].image;
  };
  rig_prediction_.reset();
  if (prior_cam_from_map) {
    rig_prediction_.emplace();
    rig_prediction_->prior_ref_from_map = *prior_cam_from_map;
    rig_prediction_->cameras.resize(n);
  }
  // Parts 0..n-1 extract camera c's features (each with its own pipeline), parts n..2n-1
  // predict camera c's points; claimed in that order by up to LocalizerOptions::rig_threads
  // threads. A camera's extraction and its prediction touch different objects (its extractor,
  // its tracker).
  const int parts = static_cast<int>(rig_prediction_ ? 2 * n : n);
  pipeline_.ForEachClaimed(parts, [&](int part) {
    const size_t c = static_cast<size_t>(part) % n;
    if (image_of(c).empty()) return;
    if (static_cast<size_t>(part) < n) {
      frames[c].emplace(pipeline_.camera(c).Extract(image_of(c), &extract[c], &undistort_ms[c]));
    } else {
      rig_prediction_->cameras[c] =
          pipeline_.tracker()->PredictCamera(c, rig_prediction_->prior_ref_from_map);
    }
  });
  // Each camera's keypoints, whether or not a fix comes (a fix's share replaces these); the
  // steps' times summed over the cameras (CPU time, as a one-camera frame's).
  stats->cameras.assign(n, PoseFix::CameraSupport{});
  stats->features = 0;
  for (size_t c = 0; c < n; ++c) {
    stats->times.detect_ms += extract[c].detect_ms;
    stats->times.describe_ms += extract[c].describe_ms;
    stats->times.undistort_ms += undistort_ms[c];
    stats->cameras[c].features = frames[c] ? static_cast<int>(frames[c]->size()) : 0;
    stats->features += stats->cameras[c].features;
  }
  rig_frames_.assign(std::make_move_iterator(frames.begin() + 1),
                     std::make_move_iterator(frames.end()));
  return std::move(*frames[0]);
}

PoseFix Localizer::RelocalizeRig(const FrameInput& input, PoseFix reference_fix,
                                 const QueryFrame* frame, LocalizationResult* result) {
  // The verification re-matches in every camera's tracking features: those of this frame when
  // they were extracted, else extracted now, once, when there is a pose to verify.
  std::optional<QueryFrame> reference_frame;
  const auto verified = [&](const Rigid3d& ref_from_map) {
    const Timer timer;
    if (frame == nullptr) {
      FrameStats extraction;  // Counted as relocalization's time.
      reference_frame.emplace(ExtractRig(input, &extraction));
      frame = &*reference_frame;
    }
    PoseFix fix = pipeline_.tracker()->Polish(RigFrames(*frame), ref_from_map);
    result->stats.times.relocalize_ms += timer.ElapsedMs();
    if (fix.success) CopyFixStats(fix, &result->stats);
    return fix;
  };
  if (reference_fix.success) return verified(reference_fix.cam_from_map);
  for (size_t c = 0; c + 1 < pipeline_.size(); ++c) {
    const cv::Mat& image = input.rig_images[c].image;
    if (image.empty()) continue;
    const QueryFrame* tracking_frame =
        c < rig_frames_.size() && rig_frames_[c] ? &*rig_frames_[c] : nullptr;
    const PoseFix found =
        TryRelocalize(pipeline_.camera(c + 1), image, tracking_frame, input.timestamp_ns, result);
    if (!found.success) continue;
    // Camera c's pose moved to the reference: ref_from_map = cam_from_ref^-1 cam_from_map.
    PoseFix fix = verified(pipeline_.tracker()->cam_from_ref(c + 1).Inverse() * found.cam_from_map);
    if (fix.success) return fix;
  }
  return reference_fix;
}

Localizer::Motion Localizer::PredictMotion(const FrameInput& input, double dt_s) const {
  Motion motion;
  if (dt_s <= 0) return motion;
  const MotionOptions& o = options_.motion;
  double sigma_t = 0.0, sigma_r = 0.0;
  if (input.odom_from_cam && last_odom_from_cam_) {
    motion.cam_prev_from_cam_cur = last_odom_from_cam_->Inverse() * *input.odom_from_cam;
    sigma_t = o.odometry_translation_fraction * motion.cam_prev_from_cam_cur.translation.norm() +
              o.odometry_floor_m;
    sigma_r = o.odometry_rotation_fraction *
                  RotationAngleDeg(motion.cam_prev_from_cam_cur.rotation) * M_PI / 180.0 +
              o.odometry_floor_deg * M_PI / 180.0;
    motion.from_sensors = true;
  } else {
    if (velocity_valid_) motion.cam_prev_from_cam_cur = ExpSe3(velocity_ * dt_s);
    const double inflate = velocity_valid_ ? 1.0 : o.unknown_velocity_noise_scale;
    sigma_t = inflate * o.velocity_sigma_mps * dt_s;
    sigma_r = inflate * o.velocity_sigma_degps * M_PI / 180.0 * dt_s;
  }
  if (cam_from_body_rotation_ && !input.gyro.empty()) {
    // body_prev_from_body_cur = prod Exp(w_i dt_i), rate held over each sample's interval.
    Eigen::Quaterniond body_delta = Eigen::Quaterniond::Identity();
    int64_t previous_ns = *last_timestamp_ns_;
    for (const GyroSample& sample : input.gyro) {
      const double dt = NsToSeconds(std::max<int64_t>(0, sample.timestamp_ns - previous_ns));
      previous_ns = std::max(previous_ns, sample.timestamp_ns);
      const Eigen::Vector3d angle = sample.rate_radps * dt;
      if (angle.norm() > 1e-15) {
        body_delta =
            body_delta * Eigen::Quaterniond(Eigen::AngleAxisd(angle.norm(), angle.normalized()));
      }
    }
    const Eigen::Matrix3d& r_cb = *cam_from_body_rotation_;
    motion.cam_prev_from_cam_cur.rotation =
        Eigen::Quaterniond(r_cb * body_delta.toRotationMatrix() * r_cb.transpose()).normalized();
    sigma_r = o.gyro_noise_rad_sqrt_s * std::sqrt(dt_s) + o.gyro_bias_radps * dt_s;
    motion.from_sensors = true;
  }
  motion.noise.diagonal() << Eigen::Vector3d::Constant(sigma_t * sigma_t),
      Eigen::Vector3d::Constant(sigma_r * sigma_r);
  return motion;
}

void Localizer::CopyFixStats(const PoseFix& fix, FrameStats* stats) {
  stats->predicted = fix.predicted;
  stats->putatives = fix.putatives;
  stats->inliers = fix.inliers;
  stats->inlier_ratio = fix.inlier_ratio;
  stats->ransac_iterations = fix.ransac_iterations;
  stats->reproj_rmse_px = fix.reproj_rmse_px;
  stats->cameras = fix.cameras;
}

void Localizer::ApplyPlane() {
  if (!plane_ || options_.motion.plane_sigma_m <= 0 || !filter_.initialized()) return;
  filter_.UpdateHeight(plane_->first, plane_->second, options_.motion.height_m,
                       options_.motion.plane_sigma_m);
}

void Localizer::AddFixTimes(const PoseFix& fix, FrameStats* stats) {
  stats->times.predict_ms += fix.times.predict_ms;
  stats->times.project_ms += fix.times.project_ms;
  stats->times.match_ms += fix.times.match_ms;
  stats->times.pose_ms += fix.times.pose_ms;
}

bool Localizer::TrackingFeaturesFirst() const {
  return options_.relocalize_with_tracking_features_first && !relocalization_failed_;
}

bool Localizer::Strong(const PoseFix& fix) const {
  return fix.inliers >= options_.min_tracking_inliers &&
         fix.inlier_ratio >= options_.min_tracking_inlier_ratio;
}

FixEvidence Localizer::EvidenceOf(const PoseFix& fix, const Motion& motion) const {
  FixEvidence evidence;
  evidence.has_pose = filter_.initialized();
  evidence.within_gate =
      evidence.has_pose && WithinJumpGate(fix.cam_from_map.Inverse(), filter_.map_from_cam(),
                                          filter_.PositionSigmaM(), options_);
  evidence.limited_support = fix.success && fix.inliers >= options_.min_limited_inliers;
  evidence.strong = Strong(fix);
  evidence.points_well_known =
      fix.point_variance_ratio <= options_.max_tracking_point_variance_ratio;
  evidence.strongly_supported = fix.inliers >= options_.relocalization.strong_inliers;
  evidence.motion_known = velocity_valid_ || motion.from_sensors;
  // Without a known motion the prediction is only the last pose: a moving robot's fix would
  // disagree with it for no fault of its own.
  evidence.agrees = !evidence.motion_known || !evidence.has_pose || !fix.success ||
                    filter_.InnovationDistanceSq(fix.cam_from_map.Inverse(), fix.covariance) <=
                        options_.max_innovation_chi2;
  return evidence;
}

void Localizer::Accept(const PoseFix& fix, const FixDecision& decision, PoseSource source,
                       int64_t timestamp_ns, LocalizationResult* result) {
  const TrackingStatus status = decision.status;
  FilterUpdate update = decision.update;
  const Rigid3d measured = fix.cam_from_map.Inverse();
  const Matrix6d& noise = fix.covariance;
  systematic_ = fix.systematic_covariance;
  const double since_fix_s = NsToSeconds(timestamp_ns - last_fix_ns_);
  if (!filter_.initialized() ||
      (status == TrackingStatus::kRelocalized && update == FilterUpdate::kFuse)) {
    update = FilterUpdate::kRestart;
  }
  if (update == FilterUpdate::kFuse) {
    filter_.UpdatePose(measured, noise);
    ApplyPlane();
  } else {
    filter_.Reset(measured, noise);  // The prediction was wrong: nothing of it to keep.
  }
  if (update == FilterUpdate::kRestart) {
    velocity_valid_ = false;
  } else if (ever_localized_ && since_fix_s > 0 && since_fix_s <= options_.velocity_window_s) {
    velocity_ = LogSe3(last_fix_map_from_cam_.Inverse() * measured) / since_fix_s;
    velocity_valid_ = true;
  }
  last_fix_ns_ = timestamp_ns;
  last_fix_map_from_cam_ = measured;
  ever_localized_ = true;
  relocalization_failed_ = false;
  pending_.reset();
  result->status = status;
  result->source = source;
  result->has_pose = true;
  result->map_from_cam = filter_.map_from_cam();
  result->covariance = filter_.covariance() + systematic_;
}

RelocalizationResult Localizer::RelocalizeFrame(const QueryPipeline& pipeline,
                                                const QueryFrame& frame, int64_t timestamp_ns,
                                                RelocalizationReport* report) const {
  RelocalizationResult found;
  const bool local = ever_localized_ &&
                     NsToSeconds(timestamp_ns - last_fix_ns_) <= options_.local_relocalization_s;
  if (local) {
    const Eigen::Vector3d center = filter_.initialized() ? filter_.map_from_cam().translation
                                                         : last_fix_map_from_cam_.translation;
    found = pipeline.relocalizer().Relocalize(frame,
                                              RelocalizationScope{center, options_.local_radius_m});
    report->kind = RelocalizationReport::Kind::kLocal;
    report->ms += found.ms;
    report->candidates += static_cast<int>(found.candidates.size());
  }
  if (!found.success) {
    found = pipeline.relocalizer().Relocalize(frame);
    report->kind = RelocalizationReport::Kind::kGlobal;
    report->ms += found.ms;
    report->candidates += static_cast<int>(found.candidates.size());
  }
  return found;
}

PoseFix Localizer::TryRelocalize(const QueryPipeline& pipeline, const cv::Mat& image,
                                 const QueryFrame* tracking_frame, int64_t timestamp_ns,
                                 LocalizationResult* result) {
  RelocalizationReport& report = result->relocalization;
  const double report_ms_before = report.ms;
  RelocalizationResult found;
  if (tracking_frame) {
    found = RelocalizeFrame(pipeline, *tracking_frame, timestamp_ns, &report);
    ++report.feature_passes;
  }
  if (!found.success) {
    ++report.feature_passes;
    const Timer extract;
    const QueryFrame frame = pipeline.ExtractForRelocalization(image);
    report.ms += extract.ElapsedMs();
    found = RelocalizeFrame(pipeline, frame, timestamp_ns, &report);
  }
  result->stats.times.relocalize_ms += report.ms - report_ms_before;
  relocalization_failed_ = !found.success;
  report.found = found.success;
  report.keyframe = found.keyframe;
  if (found.success) CopyFixStats(found.fix, &result->stats);
  return found.fix;
}

void Localizer::NoteFrameArrival() {
  arrivals_.Observe(ArrivalPredictor::Clock::now());
  arrival_noted_ = true;
}

LocalizationResult Localizer::Process(const FrameInput& input) {
  Timer total;
  if (!std::exchange(arrival_noted_, false)) arrivals_.Observe(ArrivalPredictor::Clock::now());
  CheckInput(input);
  LocalizationResult result;
  result.timestamp_ns = input.timestamp_ns;
  const bool had_held_fix = pending_.has_value();
  const Motion motion = Predict(input);
  // The tracking features when there is a pose to track from, or a relocalization to try them
  // first; a robot that stays lost (relocalization_failed_) goes straight to the relocalization
  // features (at 752x480 the tracking features were half a millisecond of such a frame, unused).
  std::optional<QueryFrame> frame;
  const bool features_first = TrackingFeaturesFirst();
  if (const std::optional<Rigid3d> prior = Prior(input); prior || had_held_fix || features_first) {
    frame.emplace(rig()
                      ? ExtractRig(input, &result.stats,
                                   prior ? std::optional<Rigid3d>(prior->Inverse()) : std::nullopt)
                      : Extract(input.image, &result.stats));
  }
  const bool taken =
      (frame && TrackFromPrior(*frame, input, motion, &result)) ||
      (had_held_fix && ConfirmHeldFix(*frame, input.timestamp_ns, &result)) ||
      Relocalize(input, frame && features_first ? &*frame : nullptr, motion, &result);
  if (!taken) BridgeOrLose(input.timestamp_ns, motion, &result);
  rig_frames_.clear();
  rig_prediction_.reset();
  // A rig's answer names every camera, even when no features were extracted this frame.
  if (rig()) result.stats.cameras.resize(rig_.cameras.size());
  result.stats.times.total_ms = total.ElapsedMs();
  if (const std::optional<ArrivalPredictor::Expectation> next = arrivals_.Next();
      next && rig() && options_.rig_wake_ahead) {
    pipeline_.ExpectFrame(*next);
  }
  return result;
}

void Localizer::CheckInput(const FrameInput& input) const {
  if (input.image.empty() || input.image.type() != CV_8UC1) {
    throw InputError("the image must be 8-bit grey (got type " +
                     std::to_string(input.image.type()) + (input.image.empty() ? ", empty)" : ")"));
  }
  if (input.image.cols != camera_.width() || input.image.rows != camera_.height()) {
    throw InputError(StrCat("the image is ", input.image.cols, "x", input.image.rows,
                            " but the session camera is ", camera_.width(), "x", camera_.height()));
  }
  const size_t other_cameras = pipeline_.size() - 1;
  if (input.rig_images.size() != other_cameras) {
    throw InputError(StrCat("the session's rig has ", other_cameras + 1,
                            " cameras but the frame carries ", input.rig_images.size() + 1,
                            " images"));
  }
  for (size_t c = 0; c < other_cameras; ++c) {
    const RigImage& rig_image = input.rig_images[c];
    if (rig_image.image.empty()) continue;
    const int64_t skew_ns = rig_image.timestamp_ns - input.timestamp_ns;
    if (std::abs(skew_ns) > options_.max_rig_skew_ns) {
      throw InputError(StrCat("camera ", c + 1, "'s image was taken ", skew_ns / 1e6,
                              " ms from the reference camera's (at most ",
                              options_.max_rig_skew_ns / 1e6, " ms)"));
    }
    const Camera& camera = rig_.cameras[c + 1];
    if (rig_image.image.type() != CV_8UC1 || rig_image.image.cols != camera.width() ||
        rig_image.image.rows != camera.height()) {
      throw InputError(StrCat("camera ", c + 1, "'s image is ", rig_image.image.cols, "x",
                              rig_image.image.rows, " of type ", rig_image.image.type(),
                              " but the camera is ", camera.width(), "x", camera.height(),
                              " 8-bit grey"));
    }
  }
  if (last_timestamp_ns_ && input.timestamp_ns <= *last_timestamp_ns_) {
    throw InputError(StrCat("frame timestamp ", input.timestamp_ns,
                            " ns does not increase (previous ", *last_timestamp_ns_, " ns)"));
  }
}

QueryFrame Localizer::Extract(const cv::Mat& image, FrameStats* stats) const {
  ExtractStats extract;
  QueryFrame frame = reference().Extract(image, &extract, &stats->times.undistort_ms);
  stats->times.detect_ms = extract.detect_ms;
  stats->times.describe_ms = extract.describe_ms;
  stats->features = static_cast<int>(frame.size());
  return frame;
}

Localizer::Motion Localizer::Predict(const FrameInput& input) {
  const double dt_s =
      last_timestamp_ns_ ? NsToSeconds(input.timestamp_ns - *last_timestamp_ns_) : 0.0;
  const Motion motion = PredictMotion(input, dt_s);
  last_timestamp_ns_ = input.timestamp_ns;
  last_odom_from_cam_ = input.odom_from_cam;
  if (filter_.initialized()) {
    filter_.Predict(motion.cam_prev_from_cam_cur, motion.noise);
    ApplyPlane();
  }
  if (pending_) pending_->map_from_cam = pending_->map_from_cam * motion.cam_prev_from_cam_cur;
  return motion;
}

std::optional<Rigid3d> Localizer::Prior(const FrameInput& input) const {
  return filter_.initialized() ? std::optional<Rigid3d>(filter_.map_from_cam())
                               : input.map_from_cam_hint;
}

bool Localizer::TrackFromPrior(const QueryFrame& frame, const FrameInput& input,
                               const Motion& motion, LocalizationResult* result) {
  const std::optional<Rigid3d> prior = Prior(input);
  if (!prior) return false;
  const PoseFix fix = TrackFrame(frame, prior->Inverse());
  AddFixTimes(fix, &result->stats);
  CopyFixStats(fix, &result->stats);
  const FixDecision decision = DecideTrackedFix(EvidenceOf(fix, motion));
  if (decision.held()) {
    const Rigid3d found = fix.cam_from_map.Inverse();
    pending_ = Pending{found, found, input.timestamp_ns};
  }
  if (!decision.taken()) return false;
  Accept(fix, decision, PoseSource::kTracking, input.timestamp_ns, result);
  return true;
}

bool Localizer::ConfirmHeldFix(const QueryFrame& frame, int64_t timestamp_ns,
                               LocalizationResult* result) {
  if (!pending_) return false;
  const Pending held = *pending_;
  pending_.reset();
  const PoseFix fix = TrackFrame(frame, held.map_from_cam.Inverse());
  AddFixTimes(fix, &result->stats);
  const FixDecision decision = DecideConfirmation(
      fix.success && Strong(fix),
      WithinJumpGate(fix.cam_from_map.Inverse(), held.map_from_cam, 0.0, options_));
  if (!decision.taken()) return false;
  CopyFixStats(fix, &result->stats);
  // The motion from the held fix to this frame becomes the velocity.
  last_fix_map_from_cam_ = held.found_map_from_cam;
  last_fix_ns_ = held.found_ns;
  Accept(fix, decision, PoseSource::kRelocalization, timestamp_ns, result);
  return true;
}

bool Localizer::Relocalize(const FrameInput& input, const QueryFrame* frame, const Motion& motion,
                           LocalizationResult* result) {
  PoseFix fix = TryRelocalize(reference(), input.image, frame, input.timestamp_ns, result);
  if (rig()) fix = RelocalizeRig(input, std::move(fix), frame, result);
  if (!fix.success) return false;
  const FixDecision decision = DecideRelocalizedFix(EvidenceOf(fix, motion));
  if (decision.held()) {
    const Rigid3d found = fix.cam_from_map.Inverse();
    pending_ = Pending{found, found, input.timestamp_ns};
    result->relocalization.awaiting_confirmation = true;
  }
  if (!decision.taken()) return false;
  Accept(fix, decision, PoseSource::kRelocalization, input.timestamp_ns, result);
  return true;
}

void Localizer::BridgeOrLose(int64_t timestamp_ns, const Motion& motion,
                             LocalizationResult* result) {
  BridgeEvidence evidence;
  evidence.has_pose = filter_.initialized();
  evidence.motion_from_sensors = motion.from_sensors;
  evidence.since_fix_s = NsToSeconds(timestamp_ns - last_fix_ns_);
  evidence.position_sigma_m = evidence.has_pose ? filter_.PositionSigmaM() : 0.0;
  if (ShouldBridge(evidence, options_.motion)) {
    result->status = TrackingStatus::kLimited;
    result->source = PoseSource::kMotion;
    result->has_pose = true;
    result->map_from_cam = filter_.map_from_cam();
    result->covariance = filter_.covariance() + systematic_;
    return;
  }
  filter_ = MotionFilter();
  velocity_valid_ = false;
  result->status = ever_localized_ ? TrackingStatus::kLost : TrackingStatus::kInitializing;
}

}  // namespace visloc
