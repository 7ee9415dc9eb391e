#pragma once
// Mapping over the link on the wire (visloc.v1 Mapping): the stereo rig, the job's options and
// each frame's progress, to and from the mapper's types. Shared by the server (which maps) and
// the client (which streams a recording). Invalid wire data throws InputError naming the field.

#include <string>

#include "mapping/map_builder.h"
#include "proto/geometry_convert.h"
#include "visloc/v1/visloc.pb.h"

namespace visloc::proto {

struct StereoRigInput {
  Camera left;
  Camera right;
  Rigid3d right_from_left;
};

// Both cameras and the right one's pose from the left, from their poses on the body. Throws
// InputError for a missing camera, bad intrinsics, or a rig without a baseline.
StereoRigInput FromProto(const v1::StereoRig& rig, const WireLimits& limits);
void ToProto(const Camera& left, const Camera& right, const Rigid3d& body_from_left,
             const Rigid3d& body_from_right, v1::StereoRig* out);

// What a mapping job runs with: the builder's options (those of `visloc map build`), the
// smallest map it publishes and whether it may replace a map of its name.
struct MappingJobOptions {
  mapping::MapBuilderOptions builder;
  int min_points = 100;
  bool replace = false;
  bool extend = false;  // Merge into the existing map of the name (which it then replaces).
};

// Zero values take `visloc map build`'s defaults. Throws InputError for an unknown feature kind
// or thresholds out of range.
MappingJobOptions FromProto(const v1::MappingOptions& options);

// "MAPPING_FRAME_ERROR" -> "frame_error": how logs, job lists and the operator page name a state.
std::string MappingStateText(v1::MappingState state);

// A frame's answer: the builder's progress after it (state TRACKING or LOST by its tracking).
void ToProto(const mapping::MapBuilderProgress& progress, v1::MappingProgress* out);

}  // namespace visloc::proto
