#pragma once
// The Localization service: one Localize stream is one robot session (session.h) with its own
// Localizer; Relocalize answers one image without a session. Maps come from the shared
// MapCache; the engine's work runs under the shared WorkPermits.

#include <atomic>
#include <chrono>
#include <functional>
#include <string>
#include <vector>

#include "proto/convert.h"
#include "server/admission.h"
#include "server/auth.h"
#include "server/map_cache.h"
#include "server/server_status.h"
#include "server/session.h"
#include "server/work_permits.h"
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
  AdmissionOptions admission;
  proto::WireLimits wire;
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
  // The live sessions, as their last frames left them.
  std::vector<SessionStatus> sessions() const { return registry_.Snapshot(); }
  const SessionRegistry& registry() const { return registry_; }
  const WorkPermits& workers() const { return workers_; }
  // Sessions closed for idleness since the start.
  int idle_sessions_closed() const { return idle_closed_.load(); }
  // What admission control would decide for one more session now (admission.h).
  AdmissionDecision Admission() const;
  const AdmissionOptions& admission_options() const { return limits_.admission; }
  // Sessions refused because the server was at capacity, since the start.
  uint64_t sessions_refused_at_capacity() const { return refused_at_capacity_.load(); }

  // For tests: called inside a session with each frame before the engine sees it, so a test can
  // make the engine's side throw what it never should, or see what the engine gets. Set it
  // before serving.
  void SetBeforeFrameHookForTesting(BeforeFrameHook hook) { before_frame_ = std::move(hook); }
  // The most frames ever processed at once, across sessions (at most limits.workers).
  int peak_frames_in_work() const { return workers_.peak_in_use(); }

 private:
  MapCache* maps_;
  ServiceLimits limits_;
  const TokenAuth* auth_;
  WorkPermits workers_;
  std::atomic<int> active_sessions_{0};
  SessionRegistry registry_;
  BeforeFrameHook before_frame_;

  std::atomic<int> idle_closed_{0};
  std::atomic<uint64_t> refused_at_capacity_{0};
};

}  // namespace visloc::server
