#pragma once
// The Fleet service: the live sessions from the server's one registry (session.h), listed once
// or watched as a snapshot every interval. Any valid token may read them (robots and admins).

#include <atomic>

#include "server/auth.h"
#include "server/server_status.h"
#include "server/session.h"
#include "visloc/v1/visloc.grpc.pb.h"

namespace visloc::server {

// A session's entry as the wire carries it.
void ToProto(const SessionStatus& session, v1::SessionSummary* out);

class FleetService final : public v1::Fleet::Service {
 public:
  // `registry` and `auth` must outlive the service.
  FleetService(const SessionRegistry* registry, const TokenAuth* auth, int max_sessions);

  grpc::Status ListSessions(grpc::ServerContext* context, const v1::ListSessionsRequest*,
                            v1::ListSessionsResponse* response) override;
  // A snapshot every interval until the caller cancels or the server stops (Stop()).
  grpc::Status WatchSessions(grpc::ServerContext* context, const v1::WatchSessionsRequest* request,
                             grpc::ServerWriter<v1::ListSessionsResponse>* writer) override;

  // Ends every watch at its next snapshot (the server is shutting down).
  void Stop() { stopping_ = true; }

 private:
  v1::ListSessionsResponse Snapshot() const;

  const SessionRegistry* registry_;
  const TokenAuth* auth_;
  int max_sessions_;
  std::atomic<bool> stopping_{false};
};

}  // namespace visloc::server
