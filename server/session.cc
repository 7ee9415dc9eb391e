#include "server/session.h"

#include <condition_variable>
#include <deque>
#include <thread>

#include "core/util/check.h"
#include "core/util/strings.h"
#include "core/util/timer.h"
#include "server/client_errors.h"

namespace visloc::server {

uint64_t SessionRegistry::Open(SessionStatus entry) {
  std::lock_guard<std::mutex> lock(mutex_);
  ++counters_.maps[entry.map].sessions;
  entry.id = next_id_++;
  sessions_[entry.id] = entry;
  return entry.id;
}

void SessionRegistry::Update(uint64_t id, const std::function<void(SessionStatus*)>& update) {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = sessions_.find(id);
  if (it != sessions_.end()) update(&it->second);
}

void SessionRegistry::Close(uint64_t id) {
  std::lock_guard<std::mutex> lock(mutex_);
  sessions_.erase(id);
}

void SessionRegistry::Count(const std::string& map, const FrameOutcome& frame) {
  std::lock_guard<std::mutex> lock(mutex_);
  FrameCounters::PerMap& counts = counters_.maps[map];
  ++counts.frames[frame.outcome];
  counts.relocalizations += frame.relocalized;
  counts.relocalizations_found += frame.relocalized && frame.found;
  if (!frame.server_s) return;
  for (size_t b = 0; b < std::size(FrameCounters::kSecondsBuckets); ++b) {
    counters_.seconds_buckets[b] += *frame.server_s <= FrameCounters::kSecondsBuckets[b];
  }
  ++counters_.seconds_count;
  counters_.seconds_sum += *frame.server_s;
}

FrameCounters SessionRegistry::Counters() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return counters_;
}

std::vector<SessionStatus> SessionRegistry::Snapshot() const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<SessionStatus> sessions;
  sessions.reserve(sessions_.size());
  for (const auto& [id, entry] : sessions_) sessions.push_back(entry);
  return sessions;
}

LocalizationSession::LocalizationSession(std::shared_ptr<const LocalizationMap> map,
                                         const v1::SessionStart& start,
                                         const proto::WireLimits& limits, WorkPermits* workers,
                                         SessionRegistry* registry,
                                         const BeforeFrameHook& before_frame)
    : workers_(workers),
      registry_(registry),
      before_frame_(before_frame),
      rig_(proto::RigFromProto(start, limits)),
      localizer_(map, rig_, proto::FromProto(start.options())),
      map_metadata_(map->map().metadata) {
  tally_.map = start.map_name();
  if (start.rig_cameras_size() > 0) {
    tally_.camera_names.push_back("reference");
    for (const v1::RigCamera& camera : start.rig_cameras()) {
      tally_.camera_names.push_back(
          camera.name().empty() ? StrCat("camera ", tally_.camera_names.size()) : camera.name());
    }
  }
  tally_.robot_id = start.robot_id();
  tally_.started = std::chrono::system_clock::now();
  tally_.without_pose_since = tally_.started;
  tally_.id = registry_->Open(tally_);
}

LocalizationSession::~LocalizationSession() { registry_->Close(tally_.id); }

v1::LocalizeResponse LocalizationSession::Answer(const v1::LocalizeRequest& request) {
  Timer timer;
  // Before the permit and the decoding: the rhythm of the robot's frames is its camera's.
  if (request.has_frame()) localizer_.NoteFrameArrival();
  v1::LocalizeResponse response;
  const uint64_t index = tally_.frames;
  std::optional<LocalizationResult> answered;
  try {
    if (!request.has_frame()) throw InputError("expected a frame, got another SessionStart");
    // Decoding and the engine are the CPU work: one permit per core across all sessions.
    const WorkPermit permit(workers_);
    const ThreadCpuTimer work;
    v1::Frame merged;
    const v1::Frame& frame = WithCarriedImu(request.frame(), &merged);
    if (before_frame_) before_frame_(frame);
    // A rig's cameras side by side on the workers idle now.
    const SparePermits spare(workers_, static_cast<int>(rig_.cameras.size()) - 1);
    localizer_.SetRigThreads(1 + spare.taken());
    // The cameras' images decoded side by side on those threads, too.
    answered = localizer_.Process(
        proto::FromProto(frame, rig_, [this](int n, const std::function<void(int)>& decode) {
          localizer_.ForEachOnRigThreads(n, decode);
        }));
    proto::ToProto(*answered, index, &response);
    if (answered->has_pose) {
      proto::SetSitePose(map_metadata_, answered->map_from_cam, &response);
    }
    const double work_s = work.ElapsedS();
    work_s_smoothed_ = worked_frames_++ ? 0.9 * work_s_smoothed_ + 0.1 * work_s : work_s;
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
  server_ms_sum_ += ms;
  const double rate_hz = ArrivalRateHz(std::chrono::steady_clock::now());
  const auto now = std::chrono::system_clock::now();
  Record([&](SessionStatus* s) {
    ++s->frames;
    s->server_ms = ms;
    s->frame_rate_hz = rate_hz;
    s->last_frame = now;
    // A rate needs a few arrivals to mean anything.
    if (worked_frames_ >= kFramesBeforeCosted) s->cpu_load = rate_hz * work_s_smoothed_;
    if (!answered) {
      ++s->errors;
      return;
    }
    if (answered->has_pose && answered->source != PoseSource::kMotion) ++s->localized;
    s->status = answered->status;
    s->has_pose = answered->has_pose;
    s->map_from_cam = answered->map_from_cam;
    s->position_sigma_m = answered->PositionSigmaPerAxisM();
    s->inliers = answered->stats.inliers;
    s->inlier_ratio = answered->stats.inlier_ratio;
    s->camera_inliers.clear();
    for (const PoseFix::CameraSupport& camera : answered->stats.cameras) {
      s->camera_inliers.push_back(camera.inliers);
    }
    if (s->has_pose) {
      s->without_pose_since.reset();
    } else if (!s->without_pose_since) {
      s->without_pose_since = now;
    }
  });
  SessionRegistry::FrameOutcome outcome{answered ? TrackingStatusName(answered->status) : "error",
                                        ms / 1e3};
  if (answered) {
    outcome.relocalized = answered->relocalization.kind != RelocalizationReport::Kind::kNone;
    outcome.found = answered->relocalization.found;
  }
  registry_->Count(tally_.map, outcome);
  return response;
}

v1::LocalizeResponse LocalizationSession::Skipped(const v1::LocalizeRequest& request,
                                                  const std::string& reason) {
  v1::LocalizeResponse response;
  response.set_frame_index(tally_.frames);
  response.set_timestamp_ns(request.has_frame() ? request.frame().timestamp_ns() : 0);
  response.set_status(v1::STATUS_SKIPPED);
  if (!reason.empty()) response.set_error(reason);
  if (request.has_frame()) {
    const auto& imu = request.frame().imu();
    carried_imu_.insert(carried_imu_.end(), imu.begin(), imu.end());
    // 10 s of a 200 Hz IMU at most: beyond that the rotation is lost anyway (max_bridge_s).
    constexpr size_t kMaxCarried = 2000;
    if (carried_imu_.size() > kMaxCarried) {
      carried_imu_.erase(carried_imu_.begin(), carried_imu_.end() - kMaxCarried);
    }
  }
  const double rate_hz = ArrivalRateHz(std::chrono::steady_clock::now());
  Record([rate_hz](SessionStatus* s) {
    ++s->frames;
    ++s->skipped;
    s->frame_rate_hz = rate_hz;
  });
  registry_->Count(tally_.map, {"skipped", std::nullopt});
  return response;
}

// `frame` with the carried gyro samples in front of its own; `storage` holds the copy when there
// is something to carry (only after skipped frames).
const v1::Frame& LocalizationSession::WithCarriedImu(const v1::Frame& frame, v1::Frame* storage) {
  if (carried_imu_.empty()) return frame;
  *storage = frame;
  storage->clear_imu();
  for (v1::ImuSample& sample : carried_imu_) *storage->add_imu() = std::move(sample);
  for (const v1::ImuSample& sample : frame.imu()) *storage->add_imu() = sample;
  carried_imu_.clear();
  return *storage;
}

double LocalizationSession::ArrivalRateHz(std::chrono::steady_clock::time_point now) {
  // A frame rate a robot keeps for seconds: what arrived in the last 2 s (at most 256 frames).
  constexpr auto kWindow = std::chrono::seconds(2);
  arrivals_.push_back(now);
  while (arrivals_.size() > 256 || now - arrivals_.front() > kWindow) arrivals_.pop_front();
  if (arrivals_.size() < 2) return 0.0;
  const double span_s = std::chrono::duration<double>(now - arrivals_.front()).count();
  return span_s > 0 ? (arrivals_.size() - 1) / span_s : 0.0;
}

double LocalizationSession::mean_server_ms() const {
  const uint64_t answered = tally_.frames - tally_.skipped;
  return answered ? server_ms_sum_ / answered : 0.0;
}

void LocalizationSession::Refuse(const v1::LocalizeRequest& request, uint64_t index,
                                 const std::string& why, v1::LocalizeResponse* response) {
  response->Clear();
  response->set_frame_index(index);
  response->set_timestamp_ns(request.has_frame() ? request.frame().timestamp_ns() : 0);
  response->set_status(v1::STATUS_ERROR);
  response->set_error(why);
}

// The session's own copy first (read by this thread alone), then the registry's.
void LocalizationSession::Record(const std::function<void(SessionStatus*)>& update) {
  update(&tally_);
  registry_->Update(tally_.id, update);
}

namespace {

std::string RateLimitReason(double rate_hz) {
  return StrCat("over the session frame-rate limit of ", FormatFixed(rate_hz, 1),
                " Hz: frame not processed");
}

}  // namespace

SessionEnd ServeSession(
    LocalizationSession* session, FrameRateLimiter* limiter, bool newest_only,
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

}  // namespace visloc::server
