#include "proto/mapping_convert.h"

#include <cmath>

#include "core/features/features.h"
#include "core/util/check.h"
#include "core/util/strings.h"

namespace visloc::proto {

StereoRigInput FromProto(const v1::StereoRig& rig, const WireLimits& limits) {
  if (!rig.has_left() || !rig.has_right()) {
    throw InputError("rig: both cameras (left and right) are needed for stereo mapping");
  }
  StereoRigInput input{FromProto(rig.left(), limits), FromProto(rig.right(), limits),
                       Rigid3d::Identity()};
  const Rigid3d body_from_left = rig.has_body_from_left()
                                     ? FromProto(rig.body_from_left(), "rig.body_from_left")
                                     : Rigid3d::Identity();
  if (!rig.has_body_from_right()) {
    throw InputError("rig.body_from_right: the right camera's pose is needed (its baseline)");
  }
  const Rigid3d body_from_right = FromProto(rig.body_from_right(), "rig.body_from_right");
  input.right_from_left = body_from_right.Inverse() * body_from_left;
  const double baseline_m = input.right_from_left.translation.norm();
  if (!(baseline_m > 1e-3)) {
    throw InputError(StrCat("rig: the cameras are ", baseline_m * 1000,
                            " mm apart; stereo mapping needs a baseline"));
  }
  return input;
}

void ToProto(const Camera& left, const Camera& right, const Rigid3d& body_from_left,
             const Rigid3d& body_from_right, v1::StereoRig* out) {
  ToProto(left, out->mutable_left());
  ToProto(right, out->mutable_right());
  ToProto(body_from_left, out->mutable_body_from_left());
  ToProto(body_from_right, out->mutable_body_from_right());
}

MappingJobOptions FromProto(const v1::MappingOptions& options) {
  MappingJobOptions job;
  job.replace = options.replace() || options.extend();
  job.extend = options.extend();
  job.builder.features =
      DefaultFeatureSettings(options.features().empty() ? "harris_surf16" : options.features());
  if (options.keyframe_translation_m() != 0) {
    RequireRange("options.keyframe_translation_m", options.keyframe_translation_m(), 0.01, 100.0,
                 " m");
    job.builder.keyframes.translation_m = options.keyframe_translation_m();
  }
  if (options.keyframe_rotation_deg() != 0) {
    RequireRange("options.keyframe_rotation_deg", options.keyframe_rotation_deg(), 0.1, 90.0,
                 " deg");
    job.builder.keyframes.rotation_deg = options.keyframe_rotation_deg();
  }
  if (options.has_loop_closure()) job.builder.loop_closure.enabled = options.loop_closure();
  if (options.has_disparity_calibration()) {
    job.builder.disparity_calibration.enabled = options.disparity_calibration();
  }
  if (options.has_disparity_correction()) {
    if (options.has_disparity_calibration() && options.disparity_calibration()) {
      throw InputError(
          "options.disparity_correction is a known correction: it is not estimated again "
          "(disparity_calibration must be unset or false)");
    }
    const v1::DisparityCorrection& known = options.disparity_correction();
    using Limits = mapping::DisparityCalibrationOptions;
    RequireRange("options.disparity_correction.offset_px", known.offset_px(),
                 -Limits::kMaxKnownOffsetPx, Limits::kMaxKnownOffsetPx, " px");
    RequireRange("options.disparity_correction.right_camera_yaw_deg", known.right_camera_yaw_deg(),
                 -Limits::kMaxKnownYawDeg, Limits::kMaxKnownYawDeg, " deg");
    job.builder.disparity_calibration.enabled = false;
    job.builder.disparity_calibration.known = FromProto(known);
  }
  if (options.min_points() != 0) job.min_points = static_cast<int>(options.min_points());
  return job;
}

std::string MappingStateText(v1::MappingState state) {
  std::string name = v1::MappingState_Name(state);
  if (StartsWith(name, "MAPPING_")) name = name.substr(8);
  return ToLower(name);
}

void ToProto(const mapping::MapBuilderProgress& progress, v1::MappingProgress* out) {
  out->set_state(progress.last_tracked ? v1::MAPPING_TRACKING : v1::MAPPING_LOST);
  out->set_frame_index(static_cast<uint64_t>(progress.frames - 1));
  out->set_has_pose(progress.last_tracked);
  if (progress.last_tracked) ToProto(progress.map_from_cam, out->mutable_map_from_cam());
  out->set_keyframes(static_cast<uint32_t>(progress.keyframes));
  out->set_points(static_cast<uint64_t>(progress.landmarks));
  out->set_tracked(static_cast<uint32_t>(progress.tracked));
  out->set_features(static_cast<uint32_t>(progress.features));
  out->set_stereo_matches(static_cast<uint32_t>(progress.stereo_matches));
  out->set_tracking_failures(static_cast<uint32_t>(progress.tracking_failures));
  out->set_loop_closures(static_cast<uint32_t>(progress.loop_closures));
  if (!progress.last_tracked) {
    out->set_error(StrCat("tracking failed: ", progress.tracked,
                          " landmarks tracked; the frame has ", progress.features, " corners, ",
                          progress.stereo_matches, " of them matched in the right image",
                          progress.stereo_matches < 50
                              ? " (too few stereo matches: `visloc dataset check` on a recording "
                                "of this rig gives the evidence)"
                              : " (too fast a motion or too little overlap with the last frames)"));
  }
}

}  // namespace visloc::proto
