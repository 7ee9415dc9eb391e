#pragma once
// The Localization service: one Localize stream is one robot session with its own Localizer;
// Relocalize answers one image without a session. Maps come from the shared MapCache.

#include <atomic>
#include <condition_variable>
#include <mutex>
#include <string>

#include "proto/convert.h"
#include "server/auth.h"
#include "server/map_cache.h"
#include "visloc/v1/visloc.grpc.pb.h"

namespace visloc::server {

struct ServiceLimits {
  int max_sessions = 64;
  int workers = 2;  // Frames processed at once across all sessions (the engine's CPU work).
  double max_frame_rate_hz = 0.0;  // Per session; faster frames are answered SKIPPED. 0: off.
  proto::WireLimits wire;
};

// A counting semaphore: the worker pool's size as permits. Sessions wait here for their turn to
// run the engine, so N sessions share the machine's cores instead of oversubscribing them.
class WorkPermits {
 public:
  explicit WorkPermits(int permits) : free_(permits) {}
  void Acquire() {
    std::unique_lock<std::mutex> lock(mutex_);
    available_.wait(lock, [this] { return free_ > 0; });
    --free_;
  }
  void Release() {
    std::lock_guard<std::mutex> lock(mutex_);
    ++free_;
    available_.notify_one();
  }

 private:
  std::mutex mutex_;
  std::condition_variable available_;
  int free_;
};

class LocalizationService final : public v1::Localization::Service {
 public:
  // `auth` must outlive the service.
  LocalizationService(MapCache* maps, const ServiceLimits& limits, const TokenAuth* auth);

  grpc::Status Localize(
      grpc::ServerContext* context,
      grpc::ServerReaderWriter<v1::LocalizeResponse, v1::LocalizeRequest>* stream) override;
  grpc::Status Relocalize(grpc::ServerContext* context, const v1::RelocalizeRequest* request,
                          v1::RelocalizeResponse* response) override;

  int active_sessions() const { return active_sessions_.load(); }

 private:
  MapCache* maps_;
  ServiceLimits limits_;
  const TokenAuth* auth_;
  WorkPermits workers_;
  std::atomic<int> active_sessions_{0};
  std::atomic<uint64_t> next_session_id_{1};
};

// Maps an exception from loading a map or decoding a request to a gRPC status with its message.
grpc::Status StatusFromException(const std::exception& e);

}  // namespace visloc::server
