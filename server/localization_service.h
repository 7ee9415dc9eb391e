#pragma once
// The Localization service: one Localize stream is one robot session with its own Localizer;
// Relocalize answers one image without a session. Maps come from the shared MapCache.

#include <algorithm>
#include <atomic>
#include <chrono>
#include <functional>
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
  // A session that receives no frame for this long is closed (a final STATUS_CLOSED answer, then
  // the call is cancelled) and its slot freed: a robot whose link froze with its stream open
  // must not hold a slot forever. 0: off.
  std::chrono::milliseconds session_idle_timeout{30000};
  proto::WireLimits wire;
};

// A counting semaphore: the worker pool's size as permits. Sessions wait here for their turn to
// run the engine, so N sessions share the machine's cores instead of oversubscribing them.
class WorkPermits {
 public:
  explicit WorkPermits(int permits) : permits_(permits), free_(permits) {}
  void Acquire() {
    std::unique_lock<std::mutex> lock(mutex_);
    available_.wait(lock, [this] { return free_ > 0; });
    --free_;
    peak_in_use_ = std::max(peak_in_use_, permits_ - free_);
  }
  void Release() {
    std::lock_guard<std::mutex> lock(mutex_);
    ++free_;
    available_.notify_one();
  }
  // The most permits ever held at once (for tests and the session-end log).
  int peak_in_use() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return peak_in_use_;
  }

 private:
  mutable std::mutex mutex_;
  std::condition_variable available_;
  const int permits_;
  int free_;
  int peak_in_use_ = 0;
};

// Holds one permit for its scope.
class WorkPermit {
 public:
  explicit WorkPermit(WorkPermits* permits) : permits_(permits) { permits_->Acquire(); }
  ~WorkPermit() { permits_->Release(); }
  WorkPermit(const WorkPermit&) = delete;
  WorkPermit& operator=(const WorkPermit&) = delete;

 private:
  WorkPermits* permits_;
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
  // Sessions closed for idleness since the start.
  int idle_sessions_closed() const { return idle_closed_.load(); }

  // Fault injection for tests: called inside a session before the engine sees each frame, so a
  // test can make the engine's side throw what it never should. Set it before serving.
  void SetBeforeFrameHookForTesting(std::function<void()> hook) { before_frame_ = std::move(hook); }
  // The most frames ever processed at once, across sessions (at most limits.workers).
  int peak_frames_in_work() const { return workers_.peak_in_use(); }

 private:
  MapCache* maps_;
  ServiceLimits limits_;
  const TokenAuth* auth_;
  WorkPermits workers_;
  std::atomic<int> active_sessions_{0};
  std::atomic<uint64_t> next_session_id_{1};
  std::function<void()> before_frame_;

  std::atomic<int> idle_closed_{0};
};

}  // namespace visloc::server
