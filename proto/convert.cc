#include "proto/convert.h"

#include <cmath>

#include "core/image/image_codec.h"
#include "core/util/check.h"

namespace visloc::proto {
namespace {

TrackingStatus StatusFromProto(v1::Status status) {
  switch (status) {
    case v1::STATUS_TRACKING:
      return TrackingStatus::kTracking;
    case v1::STATUS_LIMITED:
      return TrackingStatus::kLimited;
    case v1::STATUS_RELOCALIZED:
      return TrackingStatus::kRelocalized;
    case v1::STATUS_LOST:
      return TrackingStatus::kLost;
    default:
      return TrackingStatus::kInitializing;
  }
}

RelocalizationReport::Kind KindFromName(const std::string& name) {
  if (name == "local") return RelocalizationReport::Kind::kLocal;
  if (name == "global") return RelocalizationReport::Kind::kGlobal;
  return RelocalizationReport::Kind::kNone;
}

// A count sent as uint32 that becomes an int: refused before the cast could wrap.
int CountInRange(const char* field, uint32_t value, uint32_t high) {
  if (value > high)
    throw InputError(StrCat(field, " is ", value, "; allowed 0 (default) to ", high));
  return static_cast<int>(value);
}

// Gyro rates beyond this are not a robot's (about 1,100 deg/s saturates common IMUs).
constexpr double kMaxGyroRadps = 50.0;
// Session option ranges: beyond them the engine is not the method any more.
constexpr uint32_t kMaxVisibilityK = 1000, kMaxRansacIterations = 100000;
constexpr double kMaxRansacErrorPx = 100.0, kMaxCameraHeightM = 10.0, kMaxRigSkewMs = 1000.0;

}  // namespace

v1::Status ToProto(TrackingStatus status) {
  switch (status) {
    case TrackingStatus::kInitializing:
      return v1::STATUS_INITIALIZING;
    case TrackingStatus::kTracking:
      return v1::STATUS_TRACKING;
    case TrackingStatus::kLimited:
      return v1::STATUS_LIMITED;
    case TrackingStatus::kRelocalized:
      return v1::STATUS_RELOCALIZED;
    case TrackingStatus::kLost:
      return v1::STATUS_LOST;
  }
  return v1::STATUS_UNSPECIFIED;
}

cv::Mat DecodeImage(const std::string& encoded, const v1::RawImage* raw, const Camera& camera) {
  cv::Mat grey;
  if (raw) {
    const uint32_t stride = raw->stride() == 0 ? raw->width() : raw->stride();
    if (raw->width() == 0 || raw->height() == 0 || stride < raw->width()) {
      throw InputError(
          StrCat("raw image: bad geometry ", raw->width(), "x", raw->height(), " stride ", stride));
    }
    if (raw->pixels().size() < static_cast<size_t>(stride) * (raw->height() - 1) + raw->width()) {
      throw InputError(StrCat("raw image: ", raw->pixels().size(), " bytes is too few for ",
                              raw->width(), "x", raw->height(), " with stride ", stride));
    }
    grey = cv::Mat(static_cast<int>(raw->height()), static_cast<int>(raw->width()), CV_8UC1,
                   const_cast<char*>(raw->pixels().data()), stride)
               .clone();
  } else {
    if (encoded.empty()) throw InputError("frame has no image");
    std::string why;
    grey = image::DecodeGrey(encoded.data(), encoded.size(), &why);
    if (grey.empty()) throw InputError(StrCat("image (", encoded.size(), " bytes): ", why));
  }
  if (grey.cols != camera.width() || grey.rows != camera.height()) {
    throw InputError(StrCat("image is ", grey.cols, "x", grey.rows, " but the session camera is ",
                            camera.width(), "x", camera.height()));
  }
  return grey;
}

namespace {

using RigImagesIn = google::protobuf::RepeatedPtrField<v1::RigImage>;

// Rig image `c` (1 for the first camera after the reference) decoded for its camera: an empty
// image where the carrier has none this time. InputError naming the image that does not fit.
RigImage RigImageOf(const RigImagesIn& in, const CameraRig& rig, size_t c) {
  const v1::RigImage& image = in[static_cast<int>(c - 1)];
  RigImage out;
  out.timestamp_ns = image.timestamp_ns();
  if (image.image_case() == v1::RigImage::IMAGE_NOT_SET) return out;
  try {
    out.image =
        DecodeImage(image.encoded(), image.has_raw() ? &image.raw() : nullptr, rig.cameras[c]);
  } catch (const InputError& e) {
    throw InputError(StrCat("rig image ", c, ": ", e.what()));
  }
  return out;
}

// The rig images a `carrier` (a frame, a request) carries, one per camera after the reference,
// each decoded for its camera (RigImageOf), and reference() run for the reference camera's: side
// by side on `parallel` where there is one, else the reference first. InputError for a count that
// is not the rig's (after the reference's own faults), or the first image in the rig's order that
// does not fit its camera.
std::vector<RigImage> DecodeRigImages(const RigImagesIn& in, const CameraRig& rig,
                                      const char* carrier, const ParallelFor& parallel,
                                      const std::function<void()>& reference) {
  const size_t others = rig.cameras.size() - 1;
  std::vector<RigImage> images(others);
  if (parallel && others > 0 && static_cast<size_t>(in.size()) == others) {
    parallel(static_cast<int>(rig.cameras.size()), [&](int c) {
      if (c == 0) {
        reference();
      } else {
        images[c - 1] = RigImageOf(in, rig, c);
      }
    });
    return images;
  }
  reference();
  if (static_cast<size_t>(in.size()) != others) {
    throw InputError(StrCat("the ", carrier, " carries ", in.size(), " rig images for a rig of ",
                            rig.cameras.size(), " cameras (", others, " besides the reference)"));
  }
  for (size_t c = 1; c <= others; ++c) images[c - 1] = RigImageOf(in, rig, c);
  return images;
}

}  // namespace

FrameInput FromProto(const v1::Frame& frame, const CameraRig& rig, const ParallelFor& parallel) {
  FrameInput input;
  std::vector<RigImage> others = DecodeRigImages(frame.rig_images(), rig, "frame", parallel, [&] {
    input = FromProto(frame, rig.cameras.at(0));
  });
  input.rig_images = std::move(others);
  return input;
}

namespace {

// `reference` placed by `body_from_reference` (the identity when null), and `others` on that body.
CameraRig RigOf(const Camera& reference, const v1::Pose* body_from_reference,
                const google::protobuf::RepeatedPtrField<v1::RigCamera>& others,
                const WireLimits& limits, const char* field) {
  constexpr size_t kMaxOthers = CameraRig::kMaxCameras - 1;
  if (static_cast<size_t>(others.size()) > kMaxOthers) {
    throw InputError(StrCat(field, ": ", others.size(), " cameras; at most ", kMaxOthers,
                            " besides the reference"));
  }
  CameraRig rig;
  rig.cameras.push_back(reference);
  rig.body_is_gyro_frame = body_from_reference != nullptr;
  rig.body_from_cam.push_back(body_from_reference ? FromProto(*body_from_reference, "body_from_cam")
                                                  : Rigid3d());
  for (const v1::RigCamera& camera : others) {
    if (!camera.has_body_from_cam()) {
      throw InputError(StrCat(field, "[", rig.cameras.size() - 1, "] has no body_from_cam"));
    }
    rig.cameras.push_back(FromProto(camera.camera(), limits));
    rig.body_from_cam.push_back(FromProto(camera.body_from_cam(), "rig_cameras.body_from_cam"));
  }
  return rig;
}

}  // namespace

CameraRig RigFromProto(const v1::SessionStart& start, const WireLimits& limits) {
  const v1::SessionOptions& options = start.options();
  return RigOf(FromProto(start.camera(), limits),
               options.has_body_from_cam() ? &options.body_from_cam() : nullptr,
               start.rig_cameras(), limits, "start.rig_cameras");
}

CameraRig RigFromProto(const v1::RelocalizeRequest& request, const Camera& reference,
                       const WireLimits& limits) {
  CameraRig rig = RigOf(reference, request.has_body_from_cam() ? &request.body_from_cam() : nullptr,
                        request.rig_cameras(), limits, "request.rig_cameras");
  rig.body_is_gyro_frame = false;  // No gyro in a single frame.
  return rig;
}

std::vector<cv::Mat> RigImagesFromProto(const v1::RelocalizeRequest& request, const CameraRig& rig,
                                        const ParallelFor& parallel) {
  cv::Mat reference;
  std::vector<RigImage> others =
      DecodeRigImages(request.rig_images(), rig, "request", parallel, [&] {
        reference =
            DecodeImage(request.encoded_image(),
                        request.has_raw_image() ? &request.raw_image() : nullptr, rig.cameras[0]);
      });
  std::vector<cv::Mat> images = {std::move(reference)};
  for (RigImage& image : others) images.push_back(std::move(image.image));
  return images;
}

FrameInput FromProto(const v1::Frame& frame, const Camera& camera) {
  FrameInput input;
  input.timestamp_ns = frame.timestamp_ns();
  input.image = DecodeImage(frame.encoded(), frame.has_raw() ? &frame.raw() : nullptr, camera);
  // A pose that is present is used, so it must be valid: an all-zero quaternion is refused, not
  // taken for "no pose".
  if (frame.has_odom_from_cam()) {
    input.odom_from_cam = FromProto(frame.odom_from_cam(), "frame.odom_from_cam");
  }
  if (frame.has_map_from_cam_hint()) {
    input.map_from_cam_hint = FromProto(frame.map_from_cam_hint(), "frame.map_from_cam_hint");
  }
  for (const v1::ImuSample& s : frame.imu()) {
    const Eigen::Vector3d rate(s.gyro_x(), s.gyro_y(), s.gyro_z());
    for (int axis = 0; axis < 3; ++axis) {
      RequireRange("frame.imu.gyro", rate[axis], -kMaxGyroRadps, kMaxGyroRadps, " rad/s");
    }
    input.gyro.push_back({s.timestamp_ns(), rate});
  }
  return input;
}

void ToProto(const FrameInput& frame, const std::string& encoded_image, v1::Frame* out) {
  out->set_timestamp_ns(frame.timestamp_ns);
  out->set_encoded(encoded_image);
  if (frame.odom_from_cam) ToProto(*frame.odom_from_cam, out->mutable_odom_from_cam());
  if (frame.map_from_cam_hint) ToProto(*frame.map_from_cam_hint, out->mutable_map_from_cam_hint());
  for (const GyroSample& g : frame.gyro) {
    v1::ImuSample* s = out->add_imu();
    s->set_timestamp_ns(g.timestamp_ns);
    s->set_gyro_x(g.rate_radps.x());
    s->set_gyro_y(g.rate_radps.y());
    s->set_gyro_z(g.rate_radps.z());
  }
}

LocalizerOptions FromProto(const v1::SessionOptions& o) {
  LocalizerOptions options;
  if (o.visibility_k() > 0) {
    options.tracker.visibility.k =
        CountInRange("options.visibility_k", o.visibility_k(), kMaxVisibilityK);
  }
  if (o.has_probability_threshold()) {
    RequireRange("options.probability_threshold", o.probability_threshold(), 0.0, 1.0);
    options.tracker.visibility.probability_threshold = o.probability_threshold();
  }
  if (o.ransac_max_error_px() != 0) {  // 0: the default.
    RequireRange("options.ransac_max_error_px", o.ransac_max_error_px(), 0.1, kMaxRansacErrorPx,
                 " px");
    options.tracker.ransac.max_error_px = o.ransac_max_error_px();
  }
  if (o.ransac_max_iterations() > 0) {
    options.tracker.ransac.max_iterations = CountInRange(
        "options.ransac_max_iterations", o.ransac_max_iterations(), kMaxRansacIterations);
  }
  if (o.has_camera_height_m()) {
    RequireRange("options.camera_height_m", o.camera_height_m(), -kMaxCameraHeightM,
                 kMaxCameraHeightM, " m");
    options.motion.plane_sigma_m = 0.02;
    options.motion.height_m = o.camera_height_m();
  }
  switch (o.prediction()) {
    case v1::PREDICTION_VISIBILITY:
      options.tracker.prediction = PredictionMode::kVisibility;
      break;
    case v1::PREDICTION_TRANSPARENT:
      options.tracker.prediction = PredictionMode::kTransparent;
      break;
    case v1::PREDICTION_BRUTE_FORCE:
      options.tracker.prediction = PredictionMode::kBruteForce;
      break;
    default:
      throw InputError(StrCat("options.prediction is ", static_cast<int>(o.prediction()),
                              "; allowed 0 (visibility), 1 (transparent), 2 (brute force)"));
  }
  if (o.drop_policy() != v1::PROCESS_ALL && o.drop_policy() != v1::NEWEST_ONLY) {
    throw InputError(StrCat("options.drop_policy is ", static_cast<int>(o.drop_policy()),
                            "; allowed 0 (process all), 1 (newest only)"));
  }
  if (o.has_body_from_cam()) FromProto(o.body_from_cam(), "options.body_from_cam");
  if (o.max_rig_skew_ms() != 0) {
    RequireRange("options.max_rig_skew_ms", o.max_rig_skew_ms(), 0.001, kMaxRigSkewMs, " ms");
    options.max_rig_skew_ns = static_cast<int64_t>(std::llround(o.max_rig_skew_ms() * 1e6));
  }
  // The ranges above keep every option inside what Check() accepts; a failure here is a bug,
  // and its text (a source location) is for the server log, not the client.
  options.Check();
  return options;
}

namespace {

void ToProto(const PoseFix::CameraSupport& camera, v1::CameraSupport* out) {
  out->set_features(camera.features);
  out->set_predicted(camera.predicted);
  out->set_putatives(camera.putatives);
  out->set_inliers(camera.inliers);
}

}  // namespace

void ToProto(const LocalizationResult& r, uint64_t frame_index, v1::LocalizeResponse* out) {
  out->set_timestamp_ns(r.timestamp_ns);
  out->set_frame_index(frame_index);
  out->set_status(ToProto(r.status));
  out->set_source(static_cast<v1::PoseSource>(static_cast<int>(r.source)));
  out->set_has_pose(r.has_pose);
  if (r.has_pose) {
    ToProto(r.map_from_cam, out->mutable_map_from_cam());
    for (int i = 0; i < 6; ++i) {
      for (int j = 0; j < 6; ++j) out->add_covariance(r.covariance(i, j));
    }
    out->set_position_sigma_m(r.PositionSigmaPerAxisM());
  }
  v1::FrameStats* s = out->mutable_stats();
  s->set_features(r.stats.features);
  s->set_predicted(r.stats.predicted);
  s->set_putatives(r.stats.putatives);
  s->set_inliers(r.stats.inliers);
  s->set_inlier_ratio(r.stats.inlier_ratio);
  s->set_ransac_iterations(r.stats.ransac_iterations);
  s->set_reproj_rmse_px(r.stats.reproj_rmse_px);
  const StepTimings& t = r.stats.times;
  v1::StepTimings* pt = out->mutable_timings();
  pt->set_detect_ms(t.detect_ms);
  pt->set_describe_ms(t.describe_ms);
  pt->set_undistort_ms(t.undistort_ms);
  pt->set_predict_ms(t.predict_ms);
  pt->set_project_ms(t.project_ms);
  pt->set_match_ms(t.match_ms);
  pt->set_pose_ms(t.pose_ms);
  pt->set_relocalize_ms(t.relocalize_ms);
  pt->set_total_ms(t.total_ms);
  v1::RelocalizationInfo* rel = out->mutable_relocalization();
  rel->set_kind(RelocalizationKindName(r.relocalization.kind));
  rel->set_found(r.relocalization.found);
  rel->set_awaiting_confirmation(r.relocalization.awaiting_confirmation);
  rel->set_keyframe(r.relocalization.keyframe);
  rel->set_candidates(r.relocalization.candidates);
  rel->set_ms(r.relocalization.ms);
  rel->set_feature_passes(r.relocalization.feature_passes);
  for (const PoseFix::CameraSupport& camera : r.stats.cameras) ToProto(camera, out->add_cameras());
}

void ToProto(const RelocalizationResult& found, v1::RelocalizeResponse* out) {
  out->set_localized(found.success);
  if (found.success) {
    ToProto(found.fix.cam_from_map.Inverse(), out->mutable_map_from_cam());
    for (int i = 0; i < 36; ++i) out->add_covariance(found.fix.TotalCovariance()(i / 6, i % 6));
    out->set_inliers(found.fix.inliers);
    out->set_inlier_ratio(found.fix.inlier_ratio);
  }
  out->set_keyframe(found.keyframe);
  out->set_feature_passes(static_cast<uint32_t>(found.feature_passes));
  if (found.success) {
    for (const PoseFix::CameraSupport& camera : found.fix.cameras) {
      ToProto(camera, out->add_cameras());
    }
  }
  for (const RelocalizationCandidate& c : found.candidates) {
    v1::RelocalizationCandidate* candidate = out->add_candidates();
    candidate->set_keyframe(c.keyframe);
    candidate->set_score(c.score);
    candidate->set_matches(c.matches);
    candidate->set_ransac_inliers(c.ransac_inliers);
    candidate->set_verified_inliers(c.verified_inliers);
    candidate->set_accepted(c.accepted);
    candidate->set_verified_putatives(c.verified_putatives);
    candidate->set_verified_inlier_ratio(c.verified_inlier_ratio);
    candidate->set_inlier_cells(c.inlier_cells);
    candidate->set_significance(c.significance);
    if (c.verified) ToProto(c.map_from_cam, candidate->mutable_map_from_cam());
  }
}

LocalizationResult FromProto(const v1::LocalizeResponse& in) {
  LocalizationResult r;
  r.timestamp_ns = in.timestamp_ns();
  r.status = StatusFromProto(in.status());
  r.source = static_cast<PoseSource>(std::clamp(static_cast<int>(in.source()), 0, 3));
  r.has_pose = in.has_pose() && in.has_map_from_cam();
  if (r.has_pose) {
    r.map_from_cam = FromProto(in.map_from_cam(), "map_from_cam");
    if (in.covariance_size() == 36) {
      for (int i = 0; i < 36; ++i) r.covariance(i / 6, i % 6) = in.covariance(i);
    }
  }
  const v1::FrameStats& s = in.stats();
  r.stats.features = static_cast<int>(s.features());
  r.stats.predicted = static_cast<int>(s.predicted());
  r.stats.putatives = static_cast<int>(s.putatives());
  r.stats.inliers = static_cast<int>(s.inliers());
  r.stats.inlier_ratio = s.inlier_ratio();
  r.stats.ransac_iterations = static_cast<int>(s.ransac_iterations());
  r.stats.reproj_rmse_px = s.reproj_rmse_px();
  const v1::StepTimings& t = in.timings();
  r.stats.times.detect_ms = t.detect_ms();
  r.stats.times.describe_ms = t.describe_ms();
  r.stats.times.undistort_ms = t.undistort_ms();
  r.stats.times.predict_ms = t.predict_ms();
  r.stats.times.project_ms = t.project_ms();
  r.stats.times.match_ms = t.match_ms();
  r.stats.times.pose_ms = t.pose_ms();
  r.stats.times.relocalize_ms = t.relocalize_ms();
  r.stats.times.total_ms = t.total_ms();
  r.relocalization.kind = KindFromName(in.relocalization().kind());
  r.relocalization.found = in.relocalization().found();
  r.relocalization.awaiting_confirmation = in.relocalization().awaiting_confirmation();
  r.relocalization.keyframe = in.relocalization().keyframe();
  r.relocalization.candidates = static_cast<int>(in.relocalization().candidates());
  r.relocalization.ms = in.relocalization().ms();
  r.relocalization.feature_passes = static_cast<int>(in.relocalization().feature_passes());
  for (const v1::CameraSupport& camera : in.cameras()) {
    r.stats.cameras.push_back(
        {static_cast<int>(camera.features()), static_cast<int>(camera.predicted()),
         static_cast<int>(camera.putatives()), static_cast<int>(camera.inliers())});
  }
  return r;
}

}  // namespace visloc::proto
