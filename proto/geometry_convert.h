#pragma once
// The wire's geometry and cameras (visloc.v1 Pose, CameraModel) to and from the core types, and
// the wire's limits. Light on purpose: it links only the camera and geometry libraries, so a
// robot-side program (the ROS node) converts poses and cameras without the localization engine.
// Invalid wire data throws InputError naming the field.

#include "core/camera/camera.h"
#include "core/camera/disparity_correction.h"
#include "core/geometry/rigid3.h"
#include "visloc/v1/visloc.pb.h"

namespace visloc::proto {

namespace v1 = ::visloc::v1;

// Limits the server enforces on what clients send (the defaults: the proto's WireLimit values).
struct WireLimits {
  int max_image_width = v1::MAX_IMAGE_SIDE_PX;
  int max_image_height = v1::MAX_IMAGE_SIDE_PX;
  int max_message_bytes = v1::MAX_MESSAGE_BYTES;
};

void ToProto(const Rigid3d& pose, v1::Pose* out);
// Throws InputError for non-finite values or a zero quaternion (normalized otherwise).
Rigid3d FromProto(const v1::Pose& pose, const char* field);

void ToProto(const Camera& camera, v1::CameraModel* out);
Camera FromProto(const v1::CameraModel& camera, const WireLimits& limits);

// A rig's disparity correction on the wire: its yaw in degrees.
void ToProto(const DisparityCorrection& correction, v1::DisparityCorrection* out);
DisparityCorrection FromProto(const v1::DisparityCorrection& correction);

// Refuses a wire value outside [low, high] (NaN too), naming the field, the value and the range.
void RequireRange(const char* field, double value, double low, double high, const char* unit = "");

}  // namespace visloc::proto
