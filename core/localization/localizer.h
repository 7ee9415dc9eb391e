#pragma once
// One robot's localization session against a prior map: the per-frame loop of seed paper 000
// (sec. 5) with the proprioceptive filter of seed paper 001. Knows nothing about transport or
// storage: the server and `visloc localize` both drive it frame by frame.
//
// Per frame:
//   1. Features with the map's detector and descriptor, on the raw (distorted) image.
//   2. Prior: the filter's pose, moved by odometry (+ gyro) when the frame carries them, else by
//      the constant-velocity model.
//   3. Guided tracking from the prior (PoseTracker). A fix that jumps implausibly far from the
//      prior is held back until the next frame confirms it (jump gating).
//   4. Without a fix: local relocalization near the last pose, then global relocalization.
//      After being lost (no prior), a relocalization is accepted at once only with strong
//      support; otherwise the next frame must confirm it.
//   5. Still without a fix: bridge with the motion prediction while the robot's own motion
//      sensors are there and the uncertainty is small (status limited), else lost: no pose.
// Statuses:
//   initializing  no pose yet since the session started;
//   tracking      a visual fix with strong support;
//   limited       a pose with weak support: few inliers, a low inlier ratio, or motion only;
//   relocalized   a visual fix from relocalization or a confirmed jump (the pose may jump);
//   lost          no pose (e.g. camera covered, or out of the map).
// The map is shared read-only; a session never modifies it.

#include <functional>
#include <memory>
#include <optional>
#include <vector>

#include <opencv2/core.hpp>

#include "core/camera/camera.h"
#include "core/features/features.h"
#include "core/localization/fix_policy.h"
#include "core/localization/localizer_options.h"
#include "core/localization/motion_filter.h"
#include "core/localization/rig_pipeline.h"
#include "core/util/arrival_predictor.h"
#include "core/util/worker_pool.h"

namespace visloc {

// Where a reported pose came from.
enum class PoseSource { kNone, kTracking, kRelocalization, kMotion };
const char* PoseSourceName(PoseSource source);

// One gyro sample in the body (IMU) frame.
struct GyroSample {
  int64_t timestamp_ns = 0;
  Eigen::Vector3d rate_radps = Eigen::Vector3d::Zero();
};

// One image of a rig's other camera (CameraRig): 8-bit grey, raw, that camera's size; empty
// when that camera gave none this frame.
struct RigImage {
  int64_t timestamp_ns = 0;
  cv::Mat image;
};

struct FrameInput {
  int64_t timestamp_ns = 0;
  cv::Mat image;  // 8-bit grey, raw (distorted), the session (reference) camera's size.
  // A rig's other cameras' images (cameras 1.. of the CameraRig, in its order); empty for one
  // camera. Each stamp within LocalizerOptions::max_rig_skew_ns of timestamp_ns.
  std::vector<RigImage> rig_images;
  // The odometry's camera pose in its own frame (only its motion between frames is used).
  std::optional<Rigid3d> odom_from_cam;
  std::vector<GyroSample> gyro;              // Samples since the previous frame.
  std::optional<Rigid3d> map_from_cam_hint;  // An external guess, used when there is no pose.
};

struct StepTimings {
  double detect_ms = 0.0;
  double describe_ms = 0.0;
  double undistort_ms = 0.0;  // Keypoints to normalized coordinates, and their search grid.
  double predict_ms = 0.0;
  double project_ms = 0.0;
  double match_ms = 0.0;
  double pose_ms = 0.0;
  double relocalize_ms = 0.0;
  double total_ms = 0.0;
};

struct FrameStats {
  int features = 0;  // Tracking's (none when the frame went straight to relocalization); a
                     // rig's over all of its cameras.
  int predicted = 0;
  int putatives = 0;
  int inliers = 0;
  double inlier_ratio = 0.0;
  int ransac_iterations = 0;
  double reproj_rmse_px = 0.0;
  StepTimings times;
  // A rig's session: each camera's share of the fix this frame (features, predicted points,
  // putatives, inliers), in the rig's order; empty for one camera.
  std::vector<PoseFix::CameraSupport> cameras;
};

struct RelocalizationReport {
  enum class Kind { kNone, kLocal, kGlobal };
  Kind kind = Kind::kNone;             // The last search tried this frame.
  bool found = false;                  // A verified pose was found.
  bool awaiting_confirmation = false;  // Found, but must be confirmed by the next frame.
  int keyframe = -1;
  int candidates = 0;
  // Feature passes: 1 with the tracking features or the relocalization features alone, 2 when
  // the tracking features found nothing and the relocalization features were extracted.
  int feature_passes = 0;
  double ms = 0.0;
};
const char* RelocalizationKindName(RelocalizationReport::Kind kind);

struct LocalizationResult {
  int64_t timestamp_ns = 0;
  TrackingStatus status = TrackingStatus::kInitializing;
  PoseSource source = PoseSource::kNone;
  bool has_pose = false;
  Rigid3d map_from_cam;
  Matrix6d covariance = Matrix6d::Zero();  // Right perturbation of map_from_cam (m, rad).
  FrameStats stats;
  RelocalizationReport relocalization;
  // The position's standard deviation per axis, sqrt(trace(covariance[0:3, 0:3]) / 3) (m): for
  // an honest covariance, the position error's norm over it follows a chi distribution with 3
  // degrees of freedom (median 1.54, 2.9% beyond 3). 0 without a pose.
  double PositionSigmaPerAxisM() const;
  // The position's covariance in the map frame (m^2): the right perturbation's translation
  // block turned by the camera's rotation. Zero without a pose.
  Eigen::Matrix3d PositionCovarianceInMap() const;
};

class Localizer {
 public:
  // `camera` is the query camera (it may differ from the map's). `body_from_cam` places the
  // camera on the body whose gyro is given; without it gyro samples are ignored. Throws
  // CheckError for a map without a visibility kernel or appearance index.
  Localizer(std::shared_ptr<const LocalizationMap> map, const Camera& camera,
            const LocalizerOptions& options,
            const std::optional<Rigid3d>& body_from_cam = std::nullopt);
  // A session over a rig of cameras (CameraRig): each frame carries an image per camera, and
  // one pose is found from all of them (RigTracker). A rig of one camera is the session above.
  Localizer(std::shared_ptr<const LocalizationMap> map, const CameraRig& rig,
            const LocalizerOptions& options);

  // Frames must come in increasing time. Throws InputError for an image of the wrong size or
  // type, and for a timestamp that does not increase.
  LocalizationResult Process(const FrameInput& input);

  const LocalizerOptions& options() const { return options_; }
  // LocalizerOptions::rig_threads from the next frame on (a server lends a rig session the
  // workers idle at each frame). The answers do not change.
  void SetRigThreads(int threads);
  // fn(i) for every i of [0, n) on the threads the rig's cameras are worked on (each i claimed
  // by the first thread free for it), before Process: a server decodes a rig frame's images
  // side by side with it, which also wakes the helpers for the frame. Rethrows what fn threw.
  void ForEachOnRigThreads(int n, const std::function<void(int i)>& fn) const;
  // The next frame has arrived, now: a server calls this as it receives a frame, before it
  // decodes it; Process calls it for a frame nobody did. From the arrivals' rhythm a rig
  // session's helpers wake themselves just before the next frame (ArrivalPredictor).
  void NoteFrameArrival();
  // What the helpers' wakes for expected frames came to (WorkerPool::ExpectationStats).
  WorkerPool::ExpectationStats rig_expectation_stats() const {
    return pipeline_.expectation_stats();
  }
  // How often a rig's helper was moved off the core of the thread calling Process.
  int64_t rig_helpers_moved() const { return pipeline_.helpers_moved(); }

 private:
  struct Motion {
    Rigid3d cam_prev_from_cam_cur;
    Matrix6d noise = Matrix6d::Zero();
    bool from_sensors = false;  // Odometry or gyro, not the constant-velocity model.
  };
  // A fix held back until the next frame confirms it.
  struct Pending {
    Rigid3d map_from_cam;        // Moved by the motion prediction to the latest frame.
    Rigid3d found_map_from_cam;  // As found, at found_ns.
    int64_t found_ns = 0;
  };

  // The steps of Process, in order; each step that returns bool says whether it took a fix.
  // Throws InputError for an image or timestamp the session cannot take.
  void CheckInput(const FrameInput& input) const;
  QueryFrame Extract(const cv::Mat& image, FrameStats* stats) const;
  // A rig's tracking features: the reference camera's returned, the others' into rig_frames_
  // (each camera on its own thread, up to LocalizerOptions::rig_threads); their time and count
  // into `stats`. With the prior the frame will be tracked from, each camera's prediction from
  // it (into rig_prediction_) runs beside the extraction: a thread done with its camera's
  // features predicts while the other still extracts, where tracking would wait for both.
  QueryFrame ExtractRig(const FrameInput& input, FrameStats* stats,
                        const std::optional<Rigid3d>& prior_cam_from_map = std::nullopt);
  // Every camera's frame for the rig's tracker: `reference` and rig_frames_.
  std::vector<const QueryFrame*> RigFrames(const QueryFrame& reference) const;
  // Guided tracking of the frame (a rig's: all of its cameras) from `prior_cam_from_map`, with
  // rig_prediction_ when it was made from it.
  PoseFix TrackFrame(const QueryFrame& frame, const Rigid3d& prior_cam_from_map);
  // A rig's relocalization: the reference camera's fix verified with every camera, or, when it
  // has none, each other camera's relocalization in turn, moved to the reference and verified.
  PoseFix RelocalizeRig(const FrameInput& input, PoseFix reference_fix, const QueryFrame* frame,
                        LocalizationResult* result);
  // The motion since the last frame, applied to the filter and to a held fix.
  Motion Predict(const FrameInput& input);
  // The pose to track from: the filter's, or the frame's external hint when the filter has none.
  std::optional<Rigid3d> Prior(const FrameInput& input) const;
  // 3. Guided tracking from Prior.
  bool TrackFromPrior(const QueryFrame& frame, const FrameInput& input, const Motion& motion,
                      LocalizationResult* result);
  // A fix held since the last frame (a jump, or a weakly supported relocalization), confirmed
  // by tracking from where the motion moved it.
  bool ConfirmHeldFix(const QueryFrame& frame, int64_t timestamp_ns, LocalizationResult* result);
  // 4. Relocalization: local around the last pose, then global; with the tracking features
  // `frame` first when given (TrackingFeaturesFirst).
  bool Relocalize(const FrameInput& input, const QueryFrame* frame, const Motion& motion,
                  LocalizationResult* result);
  // 5. No visual fix: bridged with the motion prediction, or no pose.
  void BridgeOrLose(int64_t timestamp_ns, const Motion& motion, LocalizationResult* result);

  Motion PredictMotion(const FrameInput& input, double dt_s) const;
  // What is known of `fix` (found at `map_from_cam`) against the filter's pose.
  FixEvidence EvidenceOf(const PoseFix& fix, const Motion& motion) const;
  bool Strong(const PoseFix& fix) const;
  // Whether a relocalization this frame tries the tracking features first: the option, unless
  // the last relocalization found nothing with either (relocalization_failed_).
  bool TrackingFeaturesFirst() const;
  // Relocalization of `image`: with `tracking_frame`'s features first when given, then with the
  // relocalization features when that found nothing.
  PoseFix TryRelocalize(const QueryPipeline& pipeline, const cv::Mat& image,
                        const QueryFrame* tracking_frame, int64_t timestamp_ns,
                        LocalizationResult* result);
  // Local relocalization of `frame` around the last fix when that is recent, then global when
  // that found nothing; the time and candidates go to `report`.
  RelocalizationResult RelocalizeFrame(const QueryPipeline& pipeline, const QueryFrame& frame,
                                       int64_t timestamp_ns, RelocalizationReport* report) const;
  // Takes a fix. Relocalized fixes, and any fix while the filter holds nothing, restart it.
  void Accept(const PoseFix& fix, const FixDecision& decision, PoseSource source,
              int64_t timestamp_ns, LocalizationResult* result);
  void ApplyPlane();
  static void CopyFixStats(const PoseFix& fix, FrameStats* stats);
  static void AddFixTimes(const PoseFix& fix, FrameStats* stats);

  std::shared_ptr<const LocalizationMap> map_;
  CameraRig rig_;
  Camera camera_;         // The reference camera, rig_.cameras[0].
  RigPipeline pipeline_;  // Every camera's pipeline, and a rig's tracker over all of them.
  const QueryPipeline& reference() const { return pipeline_.camera(0); }
  bool rig() const { return pipeline_.tracker() != nullptr; }  // Two or more cameras.
  LocalizerOptions options_;  // The reference pipeline's: radii scaled to its camera.
  // A rig's tracking features of this frame, cameras 1.. (none where no image came).
  std::vector<std::optional<QueryFrame>> rig_frames_;
  std::optional<RigTracker::Prediction> rig_prediction_;  // This frame's, from ExtractRig.
  ArrivalPredictor arrivals_;   // The frames' arrivals, for the rig's helpers' wakes.
  bool arrival_noted_ = false;  // NoteFrameArrival was called for the frame to come.
  std::optional<Eigen::Matrix3d> cam_from_body_rotation_;
  std::optional<std::pair<Eigen::Vector3d, double>> plane_;  // Unit normal and offset.

  MotionFilter filter_;  // Valid while there is a pose (tracking, limited or bridging).
  // The last fix's systematic covariance (the map's own error at its depth): the filter fuses
  // the keypoint noise of successive fixes, and the reported covariance adds this, which fusing
  // the same map's points again does not reduce.
  Matrix6d systematic_ = Matrix6d::Zero();
  bool ever_localized_ = false;
  // The last relocalization found nothing with either features: the robot is out of the map or
  // its camera covered, and until it is found its frames go to the full features directly (the
  // tracking features' pass would fail again and cost a second pass every frame).
  bool relocalization_failed_ = false;
  std::optional<int64_t> last_timestamp_ns_;
  std::optional<Rigid3d> last_odom_from_cam_;
  int64_t last_fix_ns_ = 0;
  Rigid3d last_fix_map_from_cam_;
  Vector6d velocity_ = Vector6d::Zero();  // Twist per second, camera frame (constant velocity).
  bool velocity_valid_ = false;
  std::optional<Pending> pending_;
};

// The plane through the keyframe centres of a map made by a ground robot (unit normal and
// offset, normal . x = offset), when they are spread in two directions and close to a plane
// (MotionOptions' plane_* thresholds).
std::optional<std::pair<Eigen::Vector3d, double>> FitKeyframePlane(
    const LocalizationMap& map, const MotionOptions& options = MotionOptions{});

}  // namespace visloc
