#include "server/localization_service.h"

#include <condition_variable>
#include <deque>
#include <thread>

#include "core/localization/query_pipeline.h"
#include "core/util/check.h"
#include "core/util/strings.h"
#include "core/util/timer.h"
#include "server/client_errors.h"
#include "server/log.h"
#include "server/rate_limiter.h"

namespace visloc::server {
namespace {

using grpc::Status;
using grpc::StatusCode;

// Figures for the session-end log line.
struct SessionTally {
  uint64_t frames = 0;
  uint64_t localized = 0;
  uint64_t errors = 0;
  uint64_t skipped = 0;
  double server_ms_sum = 0.0;
};

class Session {
 public:
  Session(std::shared_ptr<const LocalizationMap> map, const v1::SessionStart& start,
          const proto::WireLimits& limits, WorkPermits* workers,
          const std::function<void()>& before_frame)
      : workers_(workers),
        before_frame_(before_frame),
        camera_(proto::FromProto(start.camera(), limits)),
        localizer_(
            std::move(map), camera_, proto::FromProto(start.options()),
            start.options().has_body_from_cam()
                ? std::optional(proto::FromProto(start.options().body_from_cam(), "body_from_cam"))
                : std::nullopt) {}

  // One response per frame, never an exception: a bad frame gets STATUS_ERROR.
  v1::LocalizeResponse Answer(const v1::LocalizeRequest& request) {
    Timer timer;
    v1::LocalizeResponse response;
    const uint64_t index = tally_.frames++;
    try {
      if (!request.has_frame()) throw InputError("expected a frame, got another SessionStart");
      // Decoding and the engine are the CPU work: one permit per core across all sessions.
      const WorkPermit permit(workers_);
      if (before_frame_) before_frame_();
      const LocalizationResult result =
          localizer_.Process(proto::FromProto(request.frame(), camera_));
      proto::ToProto(result, index, &response);
      if (result.has_pose && result.source != PoseSource::kMotion) ++tally_.localized;
    } catch (const InputError& e) {
      Refuse(request, index, RedactForClient(e.what()), &response);
    } catch (const std::exception& e) {
      // Not the frame's fault: a bug or a resource failure. The session and the server go on;
      // the client learns only a reference into the log.
      Refuse(request, index,
             "internal server error (reference " + LogInternalError(e, "Localize: frame") +
                 " in the server log)",
             &response);
    } catch (...) {
      const std::runtime_error unknown("an exception of unknown type");
      Refuse(request, index,
             "internal server error (reference " + LogInternalError(unknown, "Localize: frame") +
                 " in the server log)",
             &response);
    }
    const double ms = timer.ElapsedMs();
    response.mutable_timings()->set_server_ms(ms);
    tally_.server_ms_sum += ms;
    return response;
  }

  // `reason` is empty for a frame dropped by NEWEST_ONLY (the client asked for that).
  v1::LocalizeResponse Skipped(const v1::LocalizeRequest& request, const std::string& reason = "") {
    v1::LocalizeResponse response;
    response.set_frame_index(tally_.frames++);
    response.set_timestamp_ns(request.has_frame() ? request.frame().timestamp_ns() : 0);
    response.set_status(v1::STATUS_SKIPPED);
    if (!reason.empty()) response.set_error(reason);
    ++tally_.skipped;
    return response;
  }

  const SessionTally& tally() const { return tally_; }

 private:
  void Refuse(const v1::LocalizeRequest& request, uint64_t index, const std::string& why,
              v1::LocalizeResponse* response) {
    response->Clear();
    response->set_frame_index(index);
    response->set_timestamp_ns(request.has_frame() ? request.frame().timestamp_ns() : 0);
    response->set_status(v1::STATUS_ERROR);
    response->set_error(why);
    ++tally_.errors;
  }

  WorkPermits* workers_;
  const std::function<void()>& before_frame_;
  Camera camera_;
  Localizer localizer_;
  SessionTally tally_;
};

std::string RateLimitReason(double rate_hz) {
  return StrCat("over the session frame-rate limit of ", FormatFixed(rate_hz, 1),
                " Hz: frame not processed");
}

// How a session's stream ended.
enum class SessionEnd { kClientDone, kIdle };

// Serves one session's frames. A reader thread queues frames as they arrive (admitted by the
// rate limiter or not, at arrival), so this thread can wait with a timeout: a session without a
// frame for `idle_timeout` is told so (a final STATUS_CLOSED answer), its call cancelled (which
// ends the reader's blocked Read) and kSessionIdle returned. PROCESS_ALL answers every admitted
// frame in turn; NEWEST_ONLY answers the newest of those queued and the others SKIPPED.
SessionEnd Serve(Session* session, FrameRateLimiter* limiter, bool newest_only,
                 std::chrono::milliseconds idle_timeout, grpc::ServerContext* context,
                 grpc::ServerReaderWriter<v1::LocalizeResponse, v1::LocalizeRequest>* stream) {
  struct Arrival {
    v1::LocalizeRequest request;
    bool admitted = true;
  };
  std::mutex mutex;
  std::condition_variable changed;
  std::deque<Arrival> queue;
  bool done = false;
  std::thread reader([&] {
    Arrival arrival;
    while (stream->Read(&arrival.request)) {
      arrival.admitted = limiter->Admit(FrameRateLimiter::Clock::now());
      std::lock_guard<std::mutex> lock(mutex);
      queue.push_back(std::move(arrival));
      changed.notify_one();
    }
    std::lock_guard<std::mutex> lock(mutex);
    done = true;
    changed.notify_one();
  });
  const auto has_work = [&] { return done || !queue.empty(); };
  SessionEnd end = SessionEnd::kClientDone;
  while (true) {
    std::deque<Arrival> batch;
    {
      std::unique_lock<std::mutex> lock(mutex);
      if (idle_timeout.count() > 0) {
        if (!changed.wait_for(lock, idle_timeout, has_work)) {
          end = SessionEnd::kIdle;
          break;
        }
      } else {
        changed.wait(lock, has_work);
      }
      if (queue.empty() && done) break;
      batch.swap(queue);
    }
    bool writing = true;
    for (size_t i = 0; i < batch.size() && writing; ++i) {
      const Arrival& arrival = batch[i];
      const bool answer = !newest_only || i + 1 == batch.size();
      if (!arrival.admitted) {
        writing =
            stream->Write(session->Skipped(arrival.request, RateLimitReason(limiter->rate_hz())));
      } else {
        writing = stream->Write(answer ? session->Answer(arrival.request)
                                       : session->Skipped(arrival.request));
      }
    }
    if (!writing) break;
  }
  if (end == SessionEnd::kIdle) {
    v1::LocalizeResponse closed;
    closed.set_status(v1::STATUS_CLOSED);
    closed.set_error(StrCat("session closed: no frame for ",
                            FormatFixed(idle_timeout.count() / 1000.0, 1),
                            " s (the server's session idle timeout)"));
    stream->Write(closed);
    context->TryCancel();  // Ends the reader's Read.
  }
  reader.join();
  return end;
}

}  // namespace

LocalizationService::LocalizationService(MapCache* maps, const ServiceLimits& limits,
                                         const TokenAuth* auth)
    : maps_(maps), limits_(limits), auth_(auth), workers_(std::max(1, limits.workers)) {
}

Status LocalizationService::Localize(
    grpc::ServerContext* context,
    grpc::ServerReaderWriter<v1::LocalizeResponse, v1::LocalizeRequest>* stream) {
  if (Status allowed = auth_->Check(*context, Role::kLocalize); !allowed.ok()) return allowed;
  v1::LocalizeRequest request;
  if (!stream->Read(&request)) return Status(StatusCode::INVALID_ARGUMENT, "empty stream");
  if (!request.has_start()) {
    return Status(StatusCode::INVALID_ARGUMENT, "the first message must be a SessionStart");
  }
  const v1::SessionStart start = request.start();
  if (++active_sessions_ > limits_.max_sessions) {
    --active_sessions_;
    return Status(StatusCode::RESOURCE_EXHAUSTED,
                  StrCat("session limit reached (", limits_.max_sessions, " concurrent sessions)"));
  }
  struct Release {
    std::atomic<int>* count;
    ~Release() { --*count; }
  } release{&active_sessions_};
  std::unique_ptr<Session> session;
  std::shared_ptr<const LocalizationMap> map;
  try {
    map = maps_->Acquire(start.map_name());
    session = std::make_unique<Session>(map, start, limits_.wire, &workers_, before_frame_);
  } catch (const std::exception& e) {
    Log("session_refused",
        {{"map", start.map_name()}, {"peer", context->peer()}, {"reason", e.what()}});
    return StatusFromException(e, "Localize: session start");
  }
  const uint64_t id = next_session_id_++;
  Log("session_start", {{"session", std::to_string(id)},
                        {"map", start.map_name()},
                        {"robot", start.robot_id()},
                        {"peer", context->peer()},
                        {"policy", v1::FrameDropPolicy_Name(start.options().drop_policy())}});
  FrameRateLimiter limiter(limits_.max_frame_rate_hz);
  const SessionEnd end = Serve(session.get(), &limiter,
                               start.options().drop_policy() == v1::NEWEST_ONLY,
                               limits_.session_idle_timeout, context, stream);
  if (end == SessionEnd::kIdle) {
    ++idle_closed_;
    Log("session_idle",
        {{"session", std::to_string(id)},
         {"idle_timeout_s", FormatFixed(limits_.session_idle_timeout.count() / 1000.0, 1)},
         {"peer", context->peer()}});
  }
  const SessionTally& t = session->tally();
  const uint64_t answered = t.frames - t.skipped;
  std::vector<std::pair<std::string, std::string>> fields = {
      {"session", std::to_string(id)},
      {"map", start.map_name()},
      {"frames", std::to_string(t.frames)},
      {"localized_fraction", FormatFixed(answered ? double(t.localized) / answered : 0.0, 3)},
      {"skipped", std::to_string(t.skipped)},
      {"errors", std::to_string(t.errors)},
      {"mean_ms", FormatFixed(answered ? t.server_ms_sum / answered : 0.0, 2)},
      {"cancelled", context->IsCancelled() ? "true" : "false"},
      {"closed_idle", end == SessionEnd::kIdle ? "true" : "false"}};
  if (map->paged()) {
    // The map's page cache, over every session on it so far.
    const PageCacheStats pages = map->page_stats();
    fields.insert(fields.end(),
                  {{"map_page_loads", std::to_string(pages.loads)},
                   {"map_page_hits", std::to_string(pages.hits)},
                   {"map_page_load_ms", FormatFixed(pages.load_ms, 1)},
                   {"map_pages_peak_live_mib", FormatFixed(pages.peak_live_bytes / 1048576.0, 1)},
                   {"map_memory_mib", FormatFixed(map->MemoryBytes() / 1048576.0, 1)}});
  }
  Log("session_end", fields);
  // An idle session's call is cancelled: the client has the reason in its final answer.
  return Status::OK;
}

Status LocalizationService::Relocalize(grpc::ServerContext* context,
                                       const v1::RelocalizeRequest* request,
                                       v1::RelocalizeResponse* response) {
  if (Status allowed = auth_->Check(*context, Role::kLocalize); !allowed.ok()) return allowed;
  try {
    Timer timer;
    auto map = maps_->Acquire(request->map_name());
    const WorkPermit permit(&workers_);
    // Without a camera model the image is taken to come from the map's own camera.
    const Camera camera = request->has_camera()
                                     ? proto::FromProto(request->camera(), limits_.wire)
                                     : map->map().camera;
    const cv::Mat image =
        proto::DecodeImage(request->encoded_image(),
                           request->has_raw_image() ? &request->raw_image() : nullptr, camera);
    // The session's query pipeline (detector settings, radii scaled to the camera), so a
    // single image is relocalized exactly as a session's first frame would be.
    const QueryPipeline pipeline(map, camera, LocalizerOptions{});
    proto::ToProto(pipeline.RelocalizeImage(image), response);
    response->set_ms(timer.ElapsedMs());
    return Status::OK;
  } catch (const std::exception& e) {
    return StatusFromException(e, "Relocalize");
  }
}

}  // namespace visloc::server
