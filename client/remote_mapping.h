#pragma once
// `visloc map build --server ADDR --name NAME --dataset DIR`: streams a recorded stereo run to
// the server's Mapping service through the client library's MappingSession, which resumes the
// job across link cuts; the server builds the map as frames arrive and publishes it under NAME
// when the run ends (server/mapping_service.h). Images go as the recording's own files
// (PNG or JPEG bytes), so the server maps exactly the pixels an offline build would.

#include <string>

#include "client/connection.h"
#include "dataset/dataset.h"
#include "visloc/v1/visloc.pb.h"

namespace visloc::cli {

struct RemoteBuildOptions {
  std::string name;
  std::string robot_id;
  v1::MappingOptions wire;  // Replace, features, keyframe thresholds, loop closure, ...
  // Frames a second to send at; 0: the recording's own rate (its timestamps); negative: as fast
  // as the server maps them.
  double rate_hz = -1.0;
  int max_in_flight = 8;  // Frames sent but not yet answered (the server's queue, bounded).
  // A broken link is retried, and the job resumed where the server has it, for this long; the
  // server keeps a broken job for its own window (visloc-server --mapping-resume-s).
  double resume_s = 30.0;
  bool progress = false;  // A progress line on stderr.
  bool json = false;
};

// Streams every frame of `dataset`, then MappingEnd, resuming the job on a new stream when the
// link breaks. Returns 0 when the map is published; throws InputError with the server's reason
// otherwise (nothing is then published).
int RemoteMapBuild(const Connection& server, const Dataset& dataset,
                   const RemoteBuildOptions& options);

}  // namespace visloc::cli
