#pragma once
// Translation between the wire types (visloc.v1 protobuf) and the core types, shared by the
// server and the client so both sides agree field by field. Invalid wire data throws
// InputError naming the field.

#include <opencv2/core.hpp>

#include "core/camera/camera.h"
#include "core/geometry/rigid3.h"
#include "core/localization/localizer.h"
#include "visloc/v1/visloc.pb.h"

namespace visloc::proto {

namespace v1 = ::visloc::v1;

// Limits the server enforces on what clients send.
struct WireLimits {
  int max_image_width = 4096;
  int max_image_height = 4096;
};

void ToProto(const Rigid3d& pose, v1::Pose* out);
// Throws InputError for non-finite values or a zero quaternion (normalized otherwise).
Rigid3d FromProto(const v1::Pose& pose, const char* field);

void ToProto(const Camera& camera, v1::CameraModel* out);
Camera FromProto(const v1::CameraModel& camera, const WireLimits& limits);

// Decodes a frame's image to 8-bit grey of exactly the camera's size.
cv::Mat DecodeImage(const std::string& encoded, const v1::RawImage* raw,
                    const Camera& camera);
FrameInput FromProto(const v1::Frame& frame, const Camera& camera);
void ToProto(const FrameInput& frame, const std::string& encoded_image, v1::Frame* out);

LocalizerOptions FromProto(const v1::SessionOptions& options);

void ToProto(const LocalizationResult& result, uint64_t frame_index, v1::LocalizeResponse* out);
// The Relocalize RPC's answer (all but `ms`, the server's whole time).
void ToProto(const RelocalizationResult& found, v1::RelocalizeResponse* out);
LocalizationResult FromProto(const v1::LocalizeResponse& response);

}  // namespace visloc::proto
