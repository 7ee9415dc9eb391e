#include "server/localization_service.h"

#include "core/localization/rig_pipeline.h"
#include "core/util/check.h"
#include "core/util/strings.h"
#include "core/util/timer.h"
#include "server/log.h"
#include "server/rate_limiter.h"
#include "server/rpc.h"

namespace visloc::server {

using grpc::Status;
using grpc::StatusCode;

LocalizationService::LocalizationService(MapCache* maps, const ServiceLimits& limits,
                                         const TokenAuth* auth)
    : maps_(maps), limits_(limits), auth_(auth), workers_(std::max(1, limits.workers)) {}

namespace {

// The session-end log line: the session's figures, a rig session's helper threads (what their
// wakes ahead of the frames came to: a frame that missed its helper waits for its wake), and a
// paged map's page cache.
void LogSessionEnd(const LocalizationSession& session, const LocalizationMap& map, SessionEnd end,
                   const grpc::ServerContext& context) {
  const SessionStatus& t = session.status();
  const uint64_t answered = t.frames - t.skipped;
  std::vector<std::pair<std::string, std::string>> fields = {
      {"session", std::to_string(t.id)},
      {"map", t.map},
      {"frames", std::to_string(t.frames)},
      {"localized_fraction", FormatFixed(answered ? double(t.localized) / answered : 0.0, 3)},
      {"skipped", std::to_string(t.skipped)},
      {"errors", std::to_string(t.errors)},
      {"mean_ms", FormatFixed(session.mean_server_ms(), 2)},
      {"cancelled", context.IsCancelled() ? "true" : "false"},
      {"closed_idle", end == SessionEnd::kIdle ? "true" : "false"}};
  if (session.cameras() > 1) {
    const WorkerPool::ExpectationStats wakes = session.helper_expectations();
    fields.insert(fields.end(), {{"cameras", std::to_string(session.cameras())},
                                 {"helper_wakes", std::to_string(wakes.wakes)},
                                 {"helper_wakes_met", std::to_string(wakes.met)},
                                 {"helper_wakes_missed", std::to_string(wakes.missed)},
                                 {"helpers_moved", std::to_string(session.helpers_moved())}});
  }
  if (map.paged()) {
    // The map's page cache, over every session on it so far.
    const PageCacheStats pages = map.page_stats();
    fields.insert(fields.end(),
                  {{"map_page_loads", std::to_string(pages.loads)},
                   {"map_page_hits", std::to_string(pages.hits)},
                   {"map_page_load_ms", FormatFixed(pages.load_ms, 1)},
                   {"map_pages_peak_live_mib", FormatFixed(pages.peak_live_bytes / 1048576.0, 1)},
                   {"map_memory_mib", FormatFixed(map.MemoryBytes() / 1048576.0, 1)}});
  }
  Log("session_end", fields);
}

// A slot among `limit` concurrent sessions, held for the scope; none when all are taken.
class SessionSlot {
 public:
  SessionSlot(std::atomic<int>* active, int limit) : active_(active) {
    held_ = ++*active_ <= limit;
    if (!held_) --*active_;
  }
  ~SessionSlot() {
    if (held_) --*active_;
  }
  bool held() const { return held_; }

 private:
  std::atomic<int>* active_;
  bool held_ = false;
};

}  // namespace

Status LocalizationService::Localize(
    grpc::ServerContext* context,
    grpc::ServerReaderWriter<v1::LocalizeResponse, v1::LocalizeRequest>* stream) {
  if (Status allowed = Authorize(*auth_, *context, Role::kLocalize); !allowed.ok()) return allowed;
  v1::LocalizeRequest request;
  if (!stream->Read(&request)) return Status(StatusCode::INVALID_ARGUMENT, "empty stream");
  if (!request.has_start()) {
    return Status(StatusCode::INVALID_ARGUMENT, "the first message must be a SessionStart");
  }
  const v1::SessionStart start = request.start();
  const SessionSlot slot(&active_sessions_, limits_.max_sessions);
  if (!slot.held()) {
    return Status(StatusCode::RESOURCE_EXHAUSTED,
                  StrCat("session limit reached (", limits_.max_sessions, " concurrent sessions)"));
  }
  const auto refused = [&](const std::exception& e) {
    Log("session_refused",
        {{"map", start.map_name()}, {"peer", context->peer()}, {"reason", e.what()}});
    return StatusFromException(e, "Localize: session start");
  };
  // A map that does not exist is said first: a lasting reason, where the load's "retry later"
  // would send the robot back again and again. A stat, not a load (what admission spares).
  try {
    maps_->CheckExists(start.map_name());
  } catch (const std::exception& e) {
    return refused(e);
  }
  // The newcomer is not yet among the active sessions the load is shared by.
  if (const AdmissionDecision admission = Admission(); !admission.admit) {
    ++refused_at_capacity_;
    Log("session_refused", {{"map", start.map_name()},
                            {"robot", start.robot_id()},
                            {"peer", context->peer()},
                            {"reason", admission.why}});
    return Status(StatusCode::RESOURCE_EXHAUSTED, admission.why);
  }
  std::unique_ptr<LocalizationSession> session;
  std::shared_ptr<const LocalizationMap> map;
  try {
    map = maps_->Acquire(start.map_name());
    session = std::make_unique<LocalizationSession>(map, start, limits_.wire, &workers_, &registry_,
                                                    before_frame_);
  } catch (const std::exception& e) {
    return refused(e);
  }
  Log("session_start", {{"session", std::to_string(session->id())},
                        {"map", start.map_name()},
                        {"robot", start.robot_id()},
                        {"peer", context->peer()},
                        {"policy", v1::FrameDropPolicy_Name(start.options().drop_policy())}});
  FrameRateLimiter limiter(limits_.max_frame_rate_hz);
  const SessionEnd end =
      ServeSession(session.get(), &limiter, start.options().drop_policy() == v1::NEWEST_ONLY,
                   limits_.session_idle_timeout, context, stream);
  if (end == SessionEnd::kIdle) {
    ++idle_closed_;
    Log("session_idle",
        {{"session", std::to_string(session->id())},
         {"idle_timeout_s", FormatFixed(limits_.session_idle_timeout.count() / 1000.0, 1)},
         {"peer", context->peer()}});
  }
  LogSessionEnd(*session, *map, end, *context);
  // An idle session's call is cancelled: the client has the reason in its final answer.
  return Status::OK;
}

AdmissionDecision LocalizationService::Admission() const {
  // The sessions listed are the ones open now (the newcomer's is not yet).
  const auto now = std::chrono::system_clock::now();
  std::vector<SessionLoad> sessions;
  for (const SessionStatus& s : registry_.Snapshot()) {
    sessions.push_back({s.cpu_load, std::chrono::duration<double>(now - s.started).count()});
  }
  return DecideAdmission(workers_.load().Over(WorkerLoad::Clock::now()), workers_.permits(),
                         sessions, limits_.admission);
}

Status LocalizationService::Relocalize(grpc::ServerContext* context,
                                       const v1::RelocalizeRequest* request,
                                       v1::RelocalizeResponse* response) {
  return HandleRpc(*auth_, *context, Role::kLocalize, "Relocalize", [&] {
    Timer timer;
    auto map = maps_->Acquire(request->map_name());
    const WorkPermit permit(&workers_);
    // Without a camera model the image is taken to come from the map's own camera.
    const Camera camera = request->has_camera() ? proto::FromProto(request->camera(), limits_.wire)
                                                : map->map().camera;
    // The session's query pipelines (detector settings, radii scaled to each camera), so a
    // single frame is relocalized exactly as a session's first frame would be; a rig's frame
    // with all of its cameras.
    const CameraRig rig = proto::RigFromProto(*request, camera, limits_.wire);
    RigPipeline pipeline(map, rig, LocalizerOptions{});
    // A rig's cameras side by side on the workers idle now, as a session's: their images
    // decoded, and their features extracted for a candidate's verification.
    const SparePermits spare(&workers_, static_cast<int>(rig.cameras.size()) - 1);
    pipeline.SetThreads(1 + spare.taken());
    const std::vector<cv::Mat> images = proto::RigImagesFromProto(
        *request, rig,
        [&](int n, const std::function<void(int)>& decode) { pipeline.ForEachClaimed(n, decode); });
    proto::ToProto(pipeline.RelocalizeImages(images), response);
    if (response->localized()) {
      proto::SetSitePose(map->map().metadata, proto::FromProto(response->map_from_cam(), "pose"),
                         response);
    }
    response->set_ms(timer.ElapsedMs());
    return Status::OK;
  });
}

}  // namespace visloc::server
