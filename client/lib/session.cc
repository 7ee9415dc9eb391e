// The client session: one worker thread owns the stream's life (connect, send, tear down,
// reconnect) and one reader thread per stream takes the answers. State shared between them and
// the application's Submit() is under one mutex; events are emitted outside it, so an on_event
// callback may call Submit().

#include <grpcpp/grpcpp.h>

#include <algorithm>
#include <condition_variable>
#include <deque>
#include <mutex>
#include <stdexcept>
#include <thread>

#include "client/lib/channel.h"
#include "client/lib/pose_math.h"
#include "visloc/client/session.h"
#include "visloc/v1/visloc.grpc.pb.h"

namespace visloc::client {
namespace {

// The frame's rig images on the wire, encoded as the session's options say (a camera with no
// image this time: a RigImage with none); their bytes.
size_t AddRigImages(const Frame& frame, const SessionOptions& options,
                    google::protobuf::RepeatedPtrField<v1::RigImage>* out) {
  size_t bytes = 0;
  for (const RigFrameImage& rig_image : frame.rig_images) {
    v1::RigImage* image = out->Add();
    image->set_timestamp_ns(rig_image.timestamp_ns);
    if (!rig_image.encoded.empty()) {
      image->set_encoded(rig_image.encoded);
    } else if (rig_image.image.empty()) {
      continue;  // That camera gave no image this time.
    } else if (options.encoding == Encoding::kRaw) {
      v1::RawImage* raw = image->mutable_raw();
      raw->set_width(rig_image.image.cols);
      raw->set_height(rig_image.image.rows);
      raw->set_pixels(EncodeImage(rig_image.image, Encoding::kRaw, 0));
    } else {
      image->set_encoded(EncodeImage(rig_image.image, options.encoding, options.jpeg_quality));
    }
    bytes += image->encoded().size() + image->raw().pixels().size();
  }
  return bytes;
}

using Clock = std::chrono::steady_clock;

double MsBetween(Clock::time_point from, Clock::time_point to) {
  return std::chrono::duration<double, std::milli>(to - from).count();
}

// How long a session refused for capacity (RESOURCE_EXHAUSTED) by every replica waits before
// asking again, doubling while it is refused.
constexpr std::chrono::milliseconds kFirstCapacityBackoff{1000};
constexpr std::chrono::milliseconds kMaxCapacityBackoff{8000};

// Statuses after which reconnecting cannot help: the request itself is refused.
bool Permanent(grpc::StatusCode code) {
  switch (code) {
    case grpc::StatusCode::INVALID_ARGUMENT:
    case grpc::StatusCode::NOT_FOUND:
    case grpc::StatusCode::PERMISSION_DENIED:
    case grpc::StatusCode::UNAUTHENTICATED:
    case grpc::StatusCode::UNIMPLEMENTED:
    case grpc::StatusCode::FAILED_PRECONDITION:
      return true;
    default:
      return false;
  }
}

std::shared_ptr<grpc::Channel> NewChannel(const SessionOptions& o, const std::string& target) {
  return NewStreamChannel(
      target, o.credentials,
      {o.keepalive_time, o.keepalive_timeout, o.backoff_initial, o.backoff_max});
}

class SessionImpl final : public Session {
 public:
  explicit SessionImpl(const SessionOptions& options) : options_(options), target_(options.server) {
    worker_ = std::thread([this] { Work(); });
  }
  ~SessionImpl() override { Close(std::chrono::milliseconds(0)); }

  bool Submit(const Frame& frame, std::string* why_not) override;
  std::optional<Event> Next(std::chrono::milliseconds wait) override;
  void Close(std::chrono::milliseconds drain) override;
  LinkState link_state() const override {
    std::lock_guard<std::mutex> lock(mutex_);
    return state_;
  }
  SessionStats stats() const override {
    std::lock_guard<std::mutex> lock(mutex_);
    return stats_;
  }

 private:
  struct Queued {
    Frame frame;
    Clock::time_point submitted;
  };
  struct InFlight {
    int64_t timestamp_ns = 0;
    Clock::time_point submitted;
    std::optional<v1::Pose> odom_from_cam;
  };
  // One open Localize call.
  struct Stream {
    std::shared_ptr<grpc::Channel> channel;
    grpc::ClientContext context;
    std::unique_ptr<grpc::ClientReaderWriter<v1::LocalizeRequest, v1::LocalizeResponse>> call;
    std::thread reader;
    bool ended = false;     // The reader saw the end (guarded by mutex_).
    std::string why_ended;  // Set when we ended it (stall) or the server did (STATUS_CLOSED).
    bool posed = false;     // An answer on this stream carried a pose.
    bool answered = false;  // The stream has answered a frame.
  };
  using Events = std::vector<Event>;
  // Refusals for capacity in a row, and the wait once every replica has refused.
  struct CapacityRefusals {
    int in_a_row = 0;
    std::chrono::milliseconds backoff = kFirstCapacityBackoff;
  };

  void Work();
  // A server at capacity refused the session: the next replica of a list at once, and once
  // every replica has refused, again only after a backoff (every robot refused would otherwise
  // knock at the link's pace). Called with no lock held.
  void TurnToNextReplica(CapacityRefusals* refusals, Events* events);
  bool OpenStream(Events* events, grpc::Status* refused);
  void ReadAnswers(Stream* stream);
  void FinishWriting();
  // Ends the stream; true when the server refused it for capacity before answering a frame.
  bool EndStream(Events* events, bool* permanent);
  bool SendNext();
  void ExpireQueued(Clock::time_point now, Events* events);
  void CheckLink(Clock::time_point now, Events* events);
  void SetState(LinkState state, const std::string& detail, Events* events);
  void Emit(Events events);
  void DropOldestQueued(const std::string& why, Events* events);
  void DropAllQueued(const std::string& why, Events* events);

  const SessionOptions options_;
  // Where the next stream goes: options_.server, its replica list turned on by each refusal for
  // capacity. The worker thread's alone.
  std::string target_;
  mutable std::mutex mutex_;
  std::condition_variable wake_;  // Queue, in-flight, stream end or closing changed.
  std::deque<Queued> queue_;
  std::deque<InFlight> in_flight_;
  std::unique_ptr<Stream> stream_;
  LinkState state_ = LinkState::kConnecting;
  SessionStats stats_;
  bool closing_ = false;
  Clock::time_point drain_until_;
  std::string refused_;  // Why the server refused the session for good.
  // Gyro samples of the frames dropped since the last one sent (bounded): a frame's samples
  // cover the time since the frame before it, and the engine integrates from the last it saw.
  std::vector<v1::ImuSample> carried_imu_;
  // The last answer with a pose, for resuming: its pose and the odometry of its frame.
  std::optional<v1::Pose> last_map_from_cam_, last_odom_from_cam_;
  std::thread worker_;

  std::mutex events_mutex_;
  std::condition_variable events_ready_;
  std::deque<Event> events_;
};

bool SessionImpl::Submit(const Frame& frame, std::string* why_not) {
  const auto refuse = [why_not](const std::string& why) {
    if (why_not) *why_not = why;
    return false;
  };
  if (frame.encoded.empty()) {
    if (frame.image.empty()) return refuse("the frame has no image");
    if (frame.image.cols != static_cast<int>(options_.camera.width()) ||
        frame.image.rows != static_cast<int>(options_.camera.height())) {
      return refuse("the image is " + std::to_string(frame.image.cols) + "x" +
                    std::to_string(frame.image.rows) + " but the session camera is " +
                    std::to_string(options_.camera.width()) + "x" +
                    std::to_string(options_.camera.height()));
    }
    if (frame.image.depth() != CV_8U) return refuse("the image is not 8-bit");
  }
  if (frame.rig_images.size() != options_.rig_cameras.size()) {
    return refuse("the frame carries " + std::to_string(frame.rig_images.size()) +
                  " rig images for " + std::to_string(options_.rig_cameras.size()) +
                  " rig cameras");
  }
  for (size_t c = 0; c < frame.rig_images.size(); ++c) {
    const cv::Mat& image = frame.rig_images[c].image;
    const v1::CameraModel& camera = options_.rig_cameras[c].camera();
    if (!frame.rig_images[c].encoded.empty() || image.empty()) continue;
    if (image.cols != static_cast<int>(camera.width()) ||
        image.rows != static_cast<int>(camera.height()) || image.depth() != CV_8U) {
      return refuse("rig camera " + std::to_string(c + 1) + "'s image is " +
                    std::to_string(image.cols) + "x" + std::to_string(image.rows) +
                    " but that camera is " + std::to_string(camera.width()) + "x" +
                    std::to_string(camera.height()) + " (8-bit)");
    }
  }
  Events events;
  {
    std::unique_lock<std::mutex> lock(mutex_);
    if (options_.wait_for_room) {
      wake_.wait(lock, [this] {
        return closing_ || !refused_.empty() ||
               static_cast<int>(queue_.size()) < options_.max_queued;
      });
    }
    if (closing_) return refuse("the session is closed");
    if (!refused_.empty()) return refuse(refused_);
    Queued queued{frame, Clock::now()};
    queued.frame.image = frame.image.clone();  // The caller may reuse its buffer.
    for (RigFrameImage& rig_image : queued.frame.rig_images) {
      rig_image.image = rig_image.image.clone();
    }
    queue_.push_back(std::move(queued));
    ++stats_.submitted;
    while (static_cast<int>(queue_.size()) > options_.max_queued) {
      DropOldestQueued("the link is slower than the camera: a newer frame replaced it", &events);
    }
  }
  wake_.notify_all();
  Emit(std::move(events));
  return true;
}

std::optional<Event> SessionImpl::Next(std::chrono::milliseconds wait) {
  std::unique_lock<std::mutex> lock(events_mutex_);
  if (!events_ready_.wait_for(lock, wait, [this] { return !events_.empty(); })) {
    return std::nullopt;
  }
  Event event = std::move(events_.front());
  events_.pop_front();
  return event;
}

void SessionImpl::Emit(Events events) {
  if (events.empty()) return;
  if (options_.on_event) {
    for (const Event& e : events) options_.on_event(e);
    return;
  }
  {
    std::lock_guard<std::mutex> lock(events_mutex_);
    for (Event& e : events) {
      events_.push_back(std::move(e));
      if (static_cast<int>(events_.size()) > options_.max_pending_events) events_.pop_front();
    }
  }
  events_ready_.notify_all();
}

void SessionImpl::SetState(LinkState state, const std::string& detail, Events* events) {
  if (state == state_) return;
  state_ = state;
  Event changed;
  changed.kind = Event::Kind::kLinkState;
  changed.link_state = state;
  changed.detail = detail;
  events->push_back(std::move(changed));
}

void SessionImpl::Close(std::chrono::milliseconds drain) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!closing_) {
      closing_ = true;
      drain_until_ = Clock::now() + drain;
    }
  }
  wake_.notify_all();
  if (worker_.joinable()) worker_.join();
}

// Removes the oldest waiting frame and reports it (kDropped: never silent); its gyro samples go
// with the next frame sent. Under mutex_.
void SessionImpl::DropOldestQueued(const std::string& why, Events* events) {
  Event dropped;
  dropped.kind = Event::Kind::kDropped;
  dropped.timestamp_ns = queue_.front().frame.timestamp_ns;
  dropped.detail = why;
  events->push_back(std::move(dropped));
  const std::vector<v1::ImuSample>& imu = queue_.front().frame.imu;
  carried_imu_.insert(carried_imu_.end(), imu.begin(), imu.end());
  constexpr size_t kMaxCarried = 2000;  // 10 s of a 200 Hz IMU (the engine bridges 3 s at most).
  if (carried_imu_.size() > kMaxCarried) {
    carried_imu_.erase(carried_imu_.begin(), carried_imu_.end() - kMaxCarried);
  }
  queue_.pop_front();
  ++stats_.dropped;
}

void SessionImpl::DropAllQueued(const std::string& why, Events* events) {
  while (!queue_.empty()) DropOldestQueued(why, events);
}

// Frames that waited longer than the deadline are of no use to a robot any more.
void SessionImpl::ExpireQueued(Clock::time_point now, Events* events) {
  if (options_.wait_for_room) return;  // A replay: every frame is sent, however late.
  while (!queue_.empty() && now - queue_.front().submitted > options_.frame_deadline) {
    DropOldestQueued(
        "stale: waited " +
            std::to_string(static_cast<int>(MsBetween(queue_.front().submitted, now))) +
            " ms for the link",
        events);
  }
}

// Degraded when the oldest frame on the wire is unanswered past the deadline; stalled (the
// stream is ended, to be reopened) past the stall timeout.
void SessionImpl::CheckLink(Clock::time_point now, Events* events) {
  if (!stream_ || stream_->ended || in_flight_.empty()) return;
  const auto waited = now - in_flight_.front().submitted;
  // A stream's first answer also waits for the server to load the map: a longer allowance.
  const auto stall_after =
      stream_->answered
          ? options_.stall_timeout
          : std::max<std::chrono::milliseconds>(options_.stall_timeout, std::chrono::seconds(10));
  if (waited > stall_after) {
    stream_->why_ended =
        "stalled: no answer for " +
        std::to_string(static_cast<int>(MsBetween(in_flight_.front().submitted, now))) + " ms";
    stream_->context.TryCancel();
  } else if (waited > options_.frame_deadline && state_ == LinkState::kConnected) {
    SetState(LinkState::kDegraded,
             "no answer for over " + std::to_string(options_.frame_deadline.count()) + " ms",
             events);
  }
}

bool SessionImpl::OpenStream(Events* events, grpc::Status* refused) {
  auto stream = std::make_unique<Stream>();
  stream->channel = NewChannel(options_, target_);
  if (!stream->channel->WaitForConnected(std::chrono::system_clock::now() +
                                         options_.connect_timeout)) {
    *refused = grpc::Status(grpc::StatusCode::UNAVAILABLE, "cannot connect to " + options_.server);
    return false;
  }
  Authorize(&stream->context, options_.credentials);
  stream->call = v1::Localization::NewStub(stream->channel)->Localize(&stream->context);
  v1::LocalizeRequest start;
  v1::SessionStart* s = start.mutable_start();
  s->set_map_name(options_.map_name);
  *s->mutable_camera() = options_.camera;
  for (const v1::RigCamera& camera : options_.rig_cameras) *s->add_rig_cameras() = camera;
  *s->mutable_options() = options_.session;
  s->set_robot_id(options_.robot_id);
  if (!stream->call->Write(start)) {
    *refused = stream->call->Finish();
    return false;
  }
  std::lock_guard<std::mutex> lock(mutex_);
  stream_ = std::move(stream);
  Stream* raw = stream_.get();
  stream_->reader = std::thread([this, raw] { ReadAnswers(raw); });
  ++stats_.streams_opened;
  SetState(LinkState::kConnected,
           stats_.streams_opened == 1 ? "connected to " + options_.server : "resumed", events);
  return true;
}

void SessionImpl::ReadAnswers(Stream* stream) {
  v1::LocalizeResponse response;
  while (stream->call->Read(&response)) {
    Events events;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (response.status() == v1::STATUS_CLOSED) {
        stream->why_ended = "the server closed the session: " + response.error();
        continue;  // The stream ends next.
      }
      if (in_flight_.empty()) continue;  // Nothing of ours (cannot happen with a sound server).
      const InFlight sent = in_flight_.front();
      in_flight_.pop_front();
      stream->answered = true;
      const Clock::time_point now = Clock::now();
      Event answer;
      answer.timestamp_ns = sent.timestamp_ns;
      answer.latency_ms = MsBetween(sent.submitted, now);
      const bool late = now - sent.submitted > options_.frame_deadline;
      answer.kind = late ? Event::Kind::kLate : Event::Kind::kResult;
      ++(late ? stats_.late : stats_.answered);
      if (response.has_pose() && (response.status() == v1::STATUS_TRACKING ||
                                  response.status() == v1::STATUS_RELOCALIZED ||
                                  response.status() == v1::STATUS_LIMITED)) {
        last_map_from_cam_ = response.map_from_cam();
        last_odom_from_cam_ = sent.odom_from_cam;
        stream->posed = true;
      }
      answer.response = response;
      events.push_back(std::move(answer));
      if (!late && state_ == LinkState::kDegraded)
        SetState(LinkState::kConnected, "answering again", &events);
    }
    wake_.notify_all();
    Emit(std::move(events));
  }
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stream->ended = true;
  }
  wake_.notify_all();
}

// Closing: half-closes a live stream and gives the server a moment to end it cleanly (it does
// at once once it has read the half-close), so it is not logged as cancelled.
void SessionImpl::FinishWriting() {
  std::unique_lock<std::mutex> lock(mutex_);
  if (!closing_ || stream_->ended) return;
  Stream* stream = stream_.get();
  lock.unlock();
  stream->call->WritesDone();
  lock.lock();
  wake_.wait_for(lock, std::chrono::milliseconds(1000), [stream] { return stream->ended; });
}

// Tears the ended (or to-be-ended) stream down: its unanswered frames are undelivered.
bool SessionImpl::EndStream(Events* events, bool* permanent) {
  std::unique_ptr<Stream> stream;
  bool ended;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stream = std::move(stream_);
    ended = stream->ended;
  }
  // A call that ended by itself keeps its status (a cancel now would replace it).
  if (!ended) stream->context.TryCancel();
  stream->reader.join();
  const grpc::Status status = stream->call->Finish();
  std::lock_guard<std::mutex> lock(mutex_);
  *permanent = Permanent(status.error_code());
  // The server's status says most; ours (a stall we cancelled, a failed write) when there is
  // none or it is only the echo of our cancel.
  const bool ours = status.ok() || (status.error_code() == grpc::StatusCode::CANCELLED &&
                                    !stream->why_ended.empty());
  std::string why = ours ? stream->why_ended
                         : status.error_message() + " (gRPC code " +
                               std::to_string(static_cast<int>(status.error_code())) + ")";
  if (why.empty()) why = "the server ended the stream";
  // Each unanswered frame says why: a refusal (no map, a server at capacity) is not a link
  // that lost frames.
  for (const InFlight& lost : in_flight_) {
    Event undelivered;
    undelivered.kind = Event::Kind::kUndelivered;
    undelivered.timestamp_ns = lost.timestamp_ns;
    undelivered.detail = "the stream broke before its answer: " + why;
    events->push_back(std::move(undelivered));
    ++stats_.undelivered;
  }
  in_flight_.clear();
  if (*permanent) {
    refused_ = "the server refused the session: " + why;
    SetState(LinkState::kFailed, refused_, events);
    DropAllQueued(refused_, events);
  } else if (!closing_) {
    SetState(LinkState::kReconnecting, why, events);
  }
  return !stream->answered && status.error_code() == grpc::StatusCode::RESOURCE_EXHAUSTED;
}

// Sends the oldest queued frame. Called with no lock held; false when the write failed.
bool SessionImpl::SendNext() {
  Queued next;
  std::vector<v1::ImuSample> carried;
  Stream* stream;
  bool resume_hint = false;
  v1::Pose hint;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    next = std::move(queue_.front());
    queue_.pop_front();
    wake_.notify_all();  // Room in the queue (wait_for_room).
    stream = stream_.get();
    // Resuming: until the new stream has posed a frame, frames carry the last good pose, moved
    // by the odometry since, as the prior to track from.
    if (options_.resume_with_hint && stats_.streams_opened > 1 && !stream->posed &&
        last_map_from_cam_ && !next.frame.map_from_cam_hint) {
      hint = *last_map_from_cam_;
      if (last_odom_from_cam_ && next.frame.odom_from_cam) {
        hint = PropagateByOdometry(hint, *last_odom_from_cam_, *next.frame.odom_from_cam);
      }
      resume_hint = true;
    }
    in_flight_.push_back({next.frame.timestamp_ns, next.submitted, next.frame.odom_from_cam});
    carried.swap(carried_imu_);
  }
  v1::LocalizeRequest request;
  v1::Frame* f = request.mutable_frame();
  f->set_timestamp_ns(next.frame.timestamp_ns);
  if (!next.frame.encoded.empty()) {
    f->set_encoded(next.frame.encoded);
  } else if (options_.encoding == Encoding::kRaw) {
    const std::string pixels = EncodeImage(next.frame.image, Encoding::kRaw, 0);
    v1::RawImage* raw = f->mutable_raw();
    raw->set_width(next.frame.image.cols);
    raw->set_height(next.frame.image.rows);
    raw->set_pixels(pixels);
  } else {
    f->set_encoded(EncodeImage(next.frame.image, options_.encoding, options_.jpeg_quality));
  }
  const size_t rig_bytes = AddRigImages(next.frame, options_, f->mutable_rig_images());
  if (next.frame.odom_from_cam) *f->mutable_odom_from_cam() = *next.frame.odom_from_cam;
  for (const v1::ImuSample& s : carried) *f->add_imu() = s;  // Older: dropped frames'.
  for (const v1::ImuSample& s : next.frame.imu) *f->add_imu() = s;
  if (next.frame.map_from_cam_hint) {
    *f->mutable_map_from_cam_hint() = *next.frame.map_from_cam_hint;
  } else if (resume_hint) {
    *f->mutable_map_from_cam_hint() = hint;
  }
  const size_t bytes = f->encoded().size() + f->raw().pixels().size() + rig_bytes;
  const bool written = stream->call->Write(request);
  std::lock_guard<std::mutex> lock(mutex_);
  if (written) {
    ++stats_.sent;
    stats_.bytes_sent += bytes;
  }
  return written;
}

void SessionImpl::TurnToNextReplica(CapacityRefusals* refusals, Events* events) {
  ++refusals->in_a_row;
  target_ = NextReplicaFirst(target_);
  const int replicas = 1 + static_cast<int>(std::count(target_.begin(), target_.end(), ','));
  if (refusals->in_a_row % replicas != 0) return;
  Emit(std::move(*events));
  events->clear();
  std::unique_lock<std::mutex> lock(mutex_);
  wake_.wait_for(lock, refusals->backoff, [this] { return closing_; });
  refusals->backoff = std::min(refusals->backoff * 2, kMaxCapacityBackoff);
  ExpireQueued(Clock::now(), events);
}

void SessionImpl::Work() {
  std::chrono::milliseconds backoff = options_.backoff_initial;
  CapacityRefusals capacity;
  bool ever_connected = false;
  Clock::time_point last_stream = Clock::now();  // Opened, or the start.
  while (true) {
    Events events;
    // 1. No stream: open one when there is something to send (and not closing).
    bool need_stream;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      wake_.wait(lock, [this, ever_connected] {
        return stream_ || closing_ || !queue_.empty() || !ever_connected;
      });
      // Closing with frames still to send and drain time left: connect (or reconnect) for them.
      const bool draining = closing_ && !queue_.empty() && Clock::now() < drain_until_;
      need_stream = !stream_ && (!closing_ || draining) && refused_.empty();
      if (!stream_ && ((closing_ && !draining) || !refused_.empty())) {
        if (closing_) DropAllQueued("the session was closed before it was sent", &events);
        SetState(closing_ ? LinkState::kClosed : state_, "closed", &events);
        lock.unlock();
        Emit(std::move(events));
        return;
      }
    }
    if (need_stream) {
      grpc::Status refused;
      if (!OpenStream(&events, &refused)) {
        std::unique_lock<std::mutex> lock(mutex_);
        // Refused for capacity before the stream was up (the server answered before our first
        // write): the next replica, as for a refusal after it.
        bool at_capacity = false;
        const std::string code =
            " (gRPC code " + std::to_string(static_cast<int>(refused.error_code())) + ")";
        const bool give_up = options_.give_up_after.count() > 0 &&
                             Clock::now() - last_stream > options_.give_up_after;
        if (give_up) {
          refused_ = "gave up after " + std::to_string(options_.give_up_after.count()) +
                     " ms without a stream: " + refused.error_message() + code;
          SetState(LinkState::kFailed, refused_, &events);
          DropAllQueued(refused_, &events);
        } else if (Permanent(refused.error_code())) {
          refused_ = "the server refused the session: " + refused.error_message() + code;
          SetState(LinkState::kFailed, refused_, &events);
          DropAllQueued(refused_, &events);
        } else {
          SetState(ever_connected ? LinkState::kReconnecting : LinkState::kConnecting,
                   refused.error_message(), &events);
          ExpireQueued(Clock::now(), &events);
          at_capacity = refused.error_code() == grpc::StatusCode::RESOURCE_EXHAUSTED;
          if (!at_capacity) {
            wake_.wait_for(lock, backoff, [this] { return closing_; });
            backoff = std::min(backoff * 2, options_.backoff_max);
          }
        }
        lock.unlock();
        if (at_capacity) TurnToNextReplica(&capacity, &events);
        wake_.notify_all();
        Emit(std::move(events));
        continue;
      }
      ever_connected = true;
      backoff = options_.backoff_initial;
      last_stream = Clock::now();
    }
    // 2. A stream is open: send while the window allows, watch the link.
    bool send = false, end = false;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      wake_.wait_for(lock, std::chrono::milliseconds(20), [this] {
        return stream_->ended || closing_ ||
               (!queue_.empty() && static_cast<int>(in_flight_.size()) < options_.max_in_flight);
      });
      const Clock::time_point now = Clock::now();
      ExpireQueued(now, &events);
      CheckLink(now, &events);
      const bool drained = queue_.empty() && in_flight_.empty();
      if (stream_->ended) {
        end = true;
      } else if (closing_ && (drained || now >= drain_until_)) {
        end = true;
      } else {
        send = !queue_.empty() && static_cast<int>(in_flight_.size()) < options_.max_in_flight;
      }
    }
    if (send && !SendNext()) {
      std::lock_guard<std::mutex> lock(mutex_);
      stream_->why_ended = "the link broke while sending";
    }
    if (end) {
      bool permanent = false;
      FinishWriting();
      const bool at_capacity = EndStream(&events, &permanent);
      last_stream = Clock::now();  // Giving up counts from the break.
      if (at_capacity) {
        TurnToNextReplica(&capacity, &events);
      } else {
        capacity = CapacityRefusals();
      }
    }
    wake_.notify_all();  // A Submit waiting for room sees drops and refusals.
    Emit(std::move(events));
  }
}

}  // namespace

std::unique_ptr<Session> Session::Open(const SessionOptions& options) {
  try {
    options.Check();
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string("visloc::client::SessionOptions: ") + e.what());
  }
  return std::make_unique<SessionImpl>(options);
}

v1::RelocalizeResponse Relocalize(const SessionOptions& options, const Frame& frame,
                                  std::chrono::milliseconds timeout) {
  if (options.server.empty() || options.map_name.empty()) {
    throw std::invalid_argument("Relocalize: the server and the map name are required");
  }
  v1::RelocalizeRequest request;
  request.set_map_name(options.map_name);
  *request.mutable_camera() = options.camera;
  request.set_encoded_image(!frame.encoded.empty()
                                ? frame.encoded
                                : EncodeImage(frame.image, options.encoding, options.jpeg_quality));
  for (const v1::RigCamera& camera : options.rig_cameras) *request.add_rig_cameras() = camera;
  if (options.session.has_body_from_cam()) {
    *request.mutable_body_from_cam() = options.session.body_from_cam();
  }
  AddRigImages(frame, options, request.mutable_rig_images());
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + timeout);
  Authorize(&context, options.credentials);
  v1::RelocalizeResponse response;
  const grpc::Status status = v1::Localization::NewStub(NewChannel(options, options.server))
                                  ->Relocalize(&context, request, &response);
  if (!status.ok()) {
    throw std::runtime_error("Relocalize: " + status.error_message() + " (" +
                             std::to_string(static_cast<int>(status.error_code())) + ")");
  }
  return response;
}

}  // namespace visloc::client
