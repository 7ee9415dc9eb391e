#pragma once
// The Localization service: one Localize stream is one robot session with its own Localizer;
// Relocalize answers one image without a session. Maps come from the shared MapCache.

#include <atomic>
#include <string>

#include "proto/convert.h"
#include "server/map_cache.h"
#include "visloc/v1/visloc.grpc.pb.h"

namespace visloc::server {

struct ServiceLimits {
  int max_sessions = 64;
  proto::WireLimits wire;
};

class LocalizationService final : public v1::Localization::Service {
 public:
  LocalizationService(MapCache* maps, const ServiceLimits& limits);

  grpc::Status Localize(
      grpc::ServerContext* context,
      grpc::ServerReaderWriter<v1::LocalizeResponse, v1::LocalizeRequest>* stream) override;
  grpc::Status Relocalize(grpc::ServerContext* context, const v1::RelocalizeRequest* request,
                          v1::RelocalizeResponse* response) override;

  int active_sessions() const { return active_sessions_.load(); }

 private:
  MapCache* maps_;
  ServiceLimits limits_;
  std::atomic<int> active_sessions_{0};
  std::atomic<uint64_t> next_session_id_{1};
};

// Maps an exception from loading a map or decoding a request to a gRPC status with its message.
grpc::Status StatusFromException(const std::exception& e);

}  // namespace visloc::server
