#pragma once
// Translation between the wire types (visloc.v1 protobuf) and the localization engine's types
// (frames, session options, results), shared by the server and the client so both sides agree
// field by field; poses and cameras are geometry_convert.h's. Invalid wire data throws
// InputError naming the field.

#include <functional>

#include <opencv2/core.hpp>

#include "core/localization/localizer.h"
#include "proto/geometry_convert.h"
#include "visloc/v1/visloc.pb.h"

namespace visloc::proto {

// fn(i) for every i of [0, n), on as many threads as the caller has for it (a rig session's:
// Localizer::ForEachOnRigThreads); rethrows an exception fn threw.
using ParallelFor = std::function<void(int n, const std::function<void(int i)>& fn)>;

// Decodes a frame's image to 8-bit grey of exactly the camera's size.
cv::Mat DecodeImage(const std::string& encoded, const v1::RawImage* raw, const Camera& camera);
FrameInput FromProto(const v1::Frame& frame, const Camera& camera);
// A rig session's frame: the reference image of rig.cameras[0], and one rig image per other
// camera (InputError naming a missing or misfit one). With `parallel`, the cameras' images are
// decoded side by side: a JPEG of 320x240 takes 0.35-0.45 ms to decode, half the engine's time
// for a frame, so one after the other they add most of a camera's engine time to a rig frame.
FrameInput FromProto(const v1::Frame& frame, const CameraRig& rig,
                     const ParallelFor& parallel = {});
// A session's rig: the reference camera, placed by options.body_from_cam (the identity when
// unset: the body is then the reference camera), and SessionStart.rig_cameras on that body.
CameraRig RigFromProto(const v1::SessionStart& start, const WireLimits& limits);
// A Relocalize request's rig: `reference` (the request's camera, or the map's), placed by
// body_from_cam, and rig_cameras. The rig's images in `images` (the reference's first; empty
// for a camera with none), InputError naming a missing or misfit one.
CameraRig RigFromProto(const v1::RelocalizeRequest& request, const Camera& reference,
                       const WireLimits& limits);
std::vector<cv::Mat> RigImagesFromProto(const v1::RelocalizeRequest& request, const CameraRig& rig,
                                        const ParallelFor& parallel = {});
void ToProto(const FrameInput& frame, const std::string& encoded_image, v1::Frame* out);

LocalizerOptions FromProto(const v1::SessionOptions& options);

v1::Status ToProto(TrackingStatus status);

void ToProto(const LocalizationResult& result, uint64_t frame_index, v1::LocalizeResponse* out);
// The Relocalize RPC's answer (all but `ms`, the server's whole time).
void ToProto(const RelocalizationResult& found, v1::RelocalizeResponse* out);
LocalizationResult FromProto(const v1::LocalizeResponse& response);

// An answer's (LocalizeResponse, RelocalizeResponse) site_from_cam: its pose in the map's site
// frame (map.h SiteFromMap: the frame map align tied it to, else its level frame), and
// site_frame, that frame's name ("site" or "level"); both left unset for a map that records no
// up.
template <typename Response>
void SetSitePose(const MapMetadata& metadata, const Rigid3d& map_from_cam, Response* response) {
  const std::optional<Rigid3d> site_from_map = SiteFromMap(metadata);
  if (!site_from_map) return;
  ToProto(*site_from_map * map_from_cam, response->mutable_site_from_cam());
  response->set_site_frame(metadata.site ? "site" : "level");
}

}  // namespace visloc::proto
