#pragma once
// `visloc map build --server ADDR --name NAME`: streams a stereo run to the server's Mapping
// service through the client library's MappingSession, which resumes the job across link cuts;
// the server builds the map as frames arrive and publishes it under NAME when the run ends
// (server/mapping_service.h). The run is a recording (`--dataset`: its own image files, PNG or
// JPEG bytes, so the server maps exactly the pixels an offline build would) or two live cameras
// (`--camera L --camera R --camera-yaml L.yaml --camera-yaml R.yaml`; Ctrl-C ends the run).

#include <string>
#include <vector>

#include "client/connection.h"
#include "dataset/dataset.h"
#include "visloc/client/mapping_session.h"
#include "visloc/v1/visloc.pb.h"

namespace visloc::cli {

struct RemoteBuildOptions {
  std::string name;
  std::string robot_id;
  v1::MappingOptions wire;  // Replace, features, keyframe thresholds, loop closure, ...
  // Frames a second to send at; 0: the recording's own rate (its timestamps); negative: as fast
  // as the server maps them. Cameras: 0 or negative is their own pace.
  double rate_hz = -1.0;
  int max_in_flight = 8;  // Frames sent but not yet answered (the server's queue, bounded).
  // A broken link is retried, and the job resumed where the server has it, for this long; the
  // server keeps a broken job for its own window (visloc-server --mapping-resume-s).
  double resume_s = 30.0;
  bool progress = false;  // A progress line on stderr.
  bool json = false;
};

// Where a run's stereo frames come from.
class StereoFeed {
 public:
  virtual ~StereoFeed() = default;
  virtual v1::StereoRig Rig() const = 0;
  virtual size_t expected() const = 0;  // Frames, for progress (0: unknown, a live camera).
  virtual double paced_hz() const = 0;  // The pace frames come at (0: as the server answers).
  virtual bool Next(client::StereoFrame* frame) = 0;  // Paced; false at the end.
};

// Streams `feed` to a new job, then ends the run. Returns 0 when the map is published; throws
// InputError with the server's reason otherwise (nothing is then published).
int StreamToMapper(const Connection& server, StereoFeed& feed, const RemoteBuildOptions& options);
// A recording (InputError for a monocular or empty one).
int RemoteMapBuild(const Connection& server, const Dataset& dataset,
                   const RemoteBuildOptions& options);
// Two cameras (sources and sensor.yaml files, left then right), at most `frames` pairs (0: until
// their end or Ctrl-C).
int RemoteMapBuildFromCameras(const Connection& server, const std::vector<std::string>& sources,
                              const std::vector<std::string>& sensor_yamls, int frames,
                              const RemoteBuildOptions& options);

}  // namespace visloc::cli
