#include "server/fleet_service.h"

#include <algorithm>
#include <thread>

#include "proto/convert.h"
#include "server/rpc.h"

namespace visloc::server {
namespace {

using grpc::Status;

int64_t UnixNs(std::chrono::system_clock::time_point t) {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(t.time_since_epoch()).count();
}

}  // namespace

void ToProto(const SessionStatus& s, v1::SessionSummary* out) {
  out->set_session_id(s.id);
  out->set_map_name(s.map);
  out->set_robot_id(s.robot_id);
  out->set_status(proto::ToProto(s.status));
  out->set_has_pose(s.has_pose);
  if (s.has_pose) proto::ToProto(s.map_from_cam, out->mutable_map_from_cam());
  out->set_position_sigma_m(s.position_sigma_m);
  out->set_inliers(static_cast<uint32_t>(std::max(0, s.inliers)));
  out->set_inlier_ratio(s.inlier_ratio);
  out->set_frames(s.frames);
  out->set_localized(s.localized);
  out->set_skipped(s.skipped);
  out->set_errors(s.errors);
  out->set_server_ms(s.server_ms);
  out->set_frame_rate_hz(s.frame_rate_hz);
  out->set_started_unix_ns(UnixNs(s.started));
  out->set_last_frame_unix_ns(s.frames > 0 ? UnixNs(s.last_frame) : 0);
  out->set_without_pose_since_unix_ns(s.without_pose_since ? UnixNs(*s.without_pose_since) : 0);
}

FleetService::FleetService(const SessionRegistry* registry, const TokenAuth* auth, int max_sessions)
    : registry_(registry), auth_(auth), max_sessions_(max_sessions) {}

v1::ListSessionsResponse FleetService::Snapshot() const {
  v1::ListSessionsResponse response;
  for (const SessionStatus& session : registry_->Snapshot()) {
    ToProto(session, response.add_sessions());
  }
  response.set_server_time_unix_ns(UnixNs(std::chrono::system_clock::now()));
  response.set_max_sessions(static_cast<uint32_t>(max_sessions_));
  return response;
}

Status FleetService::ListSessions(grpc::ServerContext* context, const v1::ListSessionsRequest*,
                                  v1::ListSessionsResponse* response) {
  return HandleRpc(*auth_, *context, Role::kLocalize, "ListSessions", [&] {
    *response = Snapshot();
    return Status::OK;
  });
}

Status FleetService::WatchSessions(grpc::ServerContext* context,
                                   const v1::WatchSessionsRequest* request,
                                   grpc::ServerWriter<v1::ListSessionsResponse>* writer) {
  return HandleRpc(*auth_, *context, Role::kLocalize, "WatchSessions", [&] {
    const auto interval = std::chrono::milliseconds(
        request->interval_ms() == 0 ? 200 : std::max<uint32_t>(50, request->interval_ms()));
    auto next = std::chrono::steady_clock::now();
    while (!stopping_ && !context->IsCancelled()) {
      if (!writer->Write(Snapshot())) break;  // The watcher went away.
      next += interval;
      // Sleep in short steps, so a cancelled watch or a stopping server ends it promptly.
      while (!stopping_ && !context->IsCancelled() && std::chrono::steady_clock::now() < next) {
        std::this_thread::sleep_for(
            std::min<std::chrono::milliseconds>(interval, std::chrono::milliseconds(20)));
      }
    }
    return Status::OK;
  });
}

}  // namespace visloc::server
