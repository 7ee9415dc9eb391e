#pragma once
// The Mapping service: a robot streams a stereo run and the server builds the map with the same
// mapper as `visloc map build` (mapping::MapBuilder), fed frame by frame, answering each frame
// with the build's progress. When the client ends the stream with MappingEnd the server runs
// global bundle adjustment, visibility learning and the vocabulary, writes the map beside the
// maps folder and publishes it under its name with one atomic rename (mapstore::MapDirectory):
// sessions localizing in a replaced map keep it, new sessions get the new one. A stream that
// breaks, or ends without MappingEnd, publishes nothing.

#include <atomic>
#include <string>

#include "proto/geometry_convert.h"
#include "server/auth.h"
#include "server/map_cache.h"
#include "visloc/v1/visloc.grpc.pb.h"

namespace visloc::server {

struct MappingLimits {
  // Jobs at once; more are refused (RESOURCE_EXHAUSTED). A job holds its frames' features and
  // the map so far in memory, and takes a core while frames arrive.
  int max_jobs = 1;
  int threads = 1;  // Each job's threads (mapping::MapBuilderOptions::threads).
  // Frames one job takes; later frames are answered MAPPING_FRAME_ERROR (bounds its memory).
  int max_frames = 20000;
  bool read_only = false;  // A replica of a shared maps folder: mapping is refused.
  proto::WireLimits wire;
};

class MappingService final : public v1::Mapping::Service {
 public:
  // Every call needs the admin role. `maps` and `auth` must outlive the service.
  MappingService(MapCache* maps, const MappingLimits& limits, const TokenAuth* auth);

  grpc::Status BuildMap(
      grpc::ServerContext* context,
      grpc::ServerReaderWriter<v1::MappingProgress, v1::MappingRequest>* stream) override;

  int active_jobs() const { return active_jobs_.load(); }

 private:
  MapCache* maps_;
  MappingLimits limits_;
  const TokenAuth* auth_;
  std::atomic<int> active_jobs_{0};
};

}  // namespace visloc::server
