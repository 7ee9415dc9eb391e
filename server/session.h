#pragma once
// One robot's Localize stream on the server: its Localizer, the frames it answers, and the
// loop that serves them (a reader thread queuing arrivals, the rate limit, the drop policy, the
// idle timeout). Every live session is listed in the SessionRegistry, which it keeps current
// frame by frame (ServerStatus reads it).

#include <grpcpp/grpcpp.h>

#include <chrono>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <vector>

#include "core/localization/localizer.h"
#include "proto/convert.h"
#include "server/rate_limiter.h"
#include "server/server_status.h"
#include "server/work_permits.h"
#include "visloc/v1/visloc.grpc.pb.h"

namespace visloc::server {

// The live sessions, by id; each session's entry is its own to update.
class SessionRegistry {
 public:
  // Lists a new session under the next id (1, 2, ... in order of arrival), which it returns.
  uint64_t Open(SessionStatus entry);
  // Calls `update` on the session's entry under the registry's lock: keep it short.
  void Update(uint64_t id, const std::function<void(SessionStatus*)>& update);
  void Close(uint64_t id);
  std::vector<SessionStatus> Snapshot() const;

  // One frame of a session on `map`: its outcome (a TrackingStatusName, "skipped" or "error"),
  // its server time (answered frames) and what relocalization did.
  struct FrameOutcome {
    std::string outcome;
    std::optional<double> server_s;
    bool relocalized = false;  // Searched by appearance.
    bool found = false;
  };
  void Count(const std::string& map, const FrameOutcome& frame);
  FrameCounters Counters() const;

 private:
  mutable std::mutex mutex_;
  uint64_t next_id_ = 1;
  std::map<uint64_t, SessionStatus> sessions_;
  FrameCounters counters_;
};

// Called inside a session with each frame just before the engine sees it (tests: fault
// injection, and what reaches the engine).
using BeforeFrameHook = std::function<void(const v1::Frame& frame)>;

class LocalizationSession {
 public:
  // Throws InputError for a camera or options the wire cannot carry (named). Once
  // constructed, the session is listed in `registry` until it is destroyed.
  LocalizationSession(std::shared_ptr<const LocalizationMap> map, const v1::SessionStart& start,
                      const proto::WireLimits& limits, WorkPermits* workers,
                      SessionRegistry* registry, const BeforeFrameHook& before_frame);
  ~LocalizationSession();
  LocalizationSession(const LocalizationSession&) = delete;
  LocalizationSession& operator=(const LocalizationSession&) = delete;

  // One response per frame, never an exception: a bad frame gets STATUS_ERROR.
  v1::LocalizeResponse Answer(const v1::LocalizeRequest& request);
  // `reason` is empty for a frame dropped by NEWEST_ONLY (the client asked for that). Its gyro
  // samples go to the engine with the next frame answered.
  v1::LocalizeResponse Skipped(const v1::LocalizeRequest& request, const std::string& reason = "");

  uint64_t id() const { return tally_.id; }
  // This session's entry, as the registry holds it.
  const SessionStatus& status() const { return tally_; }
  // Mean server time of the frames answered (ms).
  double mean_server_ms() const;
  // The session's cameras (1 for a one-camera session).
  size_t cameras() const { return rig_.cameras.size(); }
  // A rig session's helper threads: their wakes ahead of expected frames, and their moves off
  // the core of the thread answering the frames (Localizer's rig_expectation_stats and
  // rig_helpers_moved).
  WorkerPool::ExpectationStats helper_expectations() const {
    return localizer_.rig_expectation_stats();
  }
  int64_t helpers_moved() const { return localizer_.rig_helpers_moved(); }

 private:
  void Refuse(const v1::LocalizeRequest& request, uint64_t index, const std::string& why,
              v1::LocalizeResponse* response);
  void Record(const std::function<void(SessionStatus*)>& update);
  const v1::Frame& WithCarriedImu(const v1::Frame& frame, v1::Frame* storage);

  WorkPermits* workers_;
  SessionRegistry* registry_;
  const BeforeFrameHook& before_frame_;
  // Gyro samples of the frames skipped since the last one answered (bounded): a frame's samples
  // cover the time since the frame before it, and the engine integrates from the last it saw.
  std::vector<v1::ImuSample> carried_imu_;
  CameraRig rig_;  // The session's cameras: the reference first (SessionStart.rig_cameras after).
  Localizer localizer_;
  const MapMetadata map_metadata_;  // For the answers' site_from_cam.
  // A frame arrived now: the arrival rate over the last 2 s.
  double ArrivalRateHz(std::chrono::steady_clock::time_point now);

  SessionStatus tally_;  // This thread's copy of the registry entry.
  double server_ms_sum_ = 0.0;
  // A frame's CPU time on its worker (decoding and the engine, s), smoothed over recent frames.
  double work_s_smoothed_ = 0.0;
  uint64_t worked_frames_ = 0;
  static constexpr uint64_t kFramesBeforeCosted = 5;
  std::deque<std::chrono::steady_clock::time_point> arrivals_;
};

// How a session's stream ended.
enum class SessionEnd { kClientDone, kIdle };

// Serves one session's frames until the client ends the stream, the stream breaks, or no frame
// arrives for `idle_timeout` (then a final STATUS_CLOSED answer and the call cancelled;
// kIdle). PROCESS_ALL answers every admitted frame in turn; NEWEST_ONLY answers the newest of
// those queued and the others SKIPPED; frames over the rate limit are answered SKIPPED.
SessionEnd ServeSession(
    LocalizationSession* session, FrameRateLimiter* limiter, bool newest_only,
    std::chrono::milliseconds idle_timeout, grpc::ServerContext* context,
    grpc::ServerReaderWriter<v1::LocalizeResponse, v1::LocalizeRequest>* stream);

}  // namespace visloc::server
