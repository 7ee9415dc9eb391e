// The mapping session: the application's thread sends (Submit, Finish) and a reader thread per
// stream takes the answers. The frames not yet answered stay in a buffer so that a resumed job
// gets those the server never saw; state shared by the two threads is under one mutex.

#include "visloc/client/mapping_session.h"

#include <grpcpp/grpcpp.h>

#include <condition_variable>
#include <deque>
#include <mutex>
#include <stdexcept>
#include <thread>

#include "client/lib/channel.h"
#include "visloc/v1/visloc.grpc.pb.h"

namespace visloc::client {

void MappingSessionOptions::Check() const {
  const auto bad = [](const std::string& what) { throw std::invalid_argument(what); };
  if (server.empty()) bad("MappingSessionOptions.server is empty");
  if (map_name.empty()) bad("MappingSessionOptions.map_name is empty");
  if (!rig.has_left() || !rig.has_right()) bad("MappingSessionOptions.rig needs both cameras");
  if (max_in_flight < 1 || max_in_flight > 64) bad("MappingSessionOptions.max_in_flight: 1..64");
  if (jpeg_quality < 1 || jpeg_quality > 100) bad("MappingSessionOptions.jpeg_quality: 1..100");
  if (resume_timeout.count() < 0 || backoff_initial.count() < 1 || backoff_max < backoff_initial) {
    bad("MappingSessionOptions: resume_timeout >= 0, 1 ms <= backoff_initial <= backoff_max");
  }
}

namespace {

using Clock = std::chrono::steady_clock;
using Stream = grpc::ClientReaderWriter<v1::MappingRequest, v1::MappingProgress>;

// Statuses after which resuming cannot help: the server refused the job or has no such job.
bool Refused(grpc::StatusCode code) {
  switch (code) {
    case grpc::StatusCode::INVALID_ARGUMENT:
    case grpc::StatusCode::ALREADY_EXISTS:
    case grpc::StatusCode::NOT_FOUND:
    case grpc::StatusCode::PERMISSION_DENIED:
    case grpc::StatusCode::UNAUTHENTICATED:
    case grpc::StatusCode::RESOURCE_EXHAUSTED:
    case grpc::StatusCode::FAILED_PRECONDITION:
    case grpc::StatusCode::UNIMPLEMENTED:
      return true;
    default:
      return false;
  }
}

bool IsFrameAnswer(v1::MappingState state) {
  return state == v1::MAPPING_TRACKING || state == v1::MAPPING_LOST ||
         state == v1::MAPPING_FRAME_ERROR;
}

std::string Describe(const grpc::Status& status) {
  return status.error_message() + " (gRPC code " + std::to_string(status.error_code()) + ")";
}

// A frame as sent: kept until its answer arrives.
struct Pending {
  v1::MappingRequest request;
  Clock::time_point submitted;
};

class MappingSessionImpl final : public MappingSession {
 public:
  explicit MappingSessionImpl(const MappingSessionOptions& options) : options_(options) {}

  ~MappingSessionImpl() override { CloseStream(/*cancel=*/true); }

  // Opens the first stream; throws with the server's reason when the job is refused.
  void Start() {
    std::string why;
    if (!OpenStream(/*resume=*/false, &why)) throw std::runtime_error(why);
  }

  bool Submit(const StereoFrame& frame, std::string* why_not) override {
    const auto refuse = [why_not](const std::string& why) {
      if (why_not) *why_not = why;
      return false;
    };
    if (!failure_.empty()) return refuse(failure_);
    Pending pending{Request(frame), Clock::now()};
    std::unique_lock<std::mutex> lock(mutex_);
    room_.wait(lock, [&] {
      return stream_done_ || static_cast<int>(unanswered_.size()) < options_.max_in_flight;
    });
    unanswered_.push_back(pending);
    ++stats_.submitted;
    stats_.bytes_sent += pending.request.frame().left_encoded().size() +
                         pending.request.frame().right_encoded().size();
    const bool broken = stream_done_;
    lock.unlock();
    if (broken || !stream_->Write(pending.request)) {
      if (!Resume()) return refuse(failure_);
    }
    return true;
  }

  std::vector<MappingAnswer> TakeAnswers() override {
    std::lock_guard<std::mutex> lock(mutex_);
    std::vector<MappingAnswer> answers;
    answers.swap(answers_);
    return answers;
  }

  v1::MappingProgress Finish() override {
    if (!failure_.empty()) throw std::runtime_error(failure_);
    for (;;) {
      v1::MappingRequest end;
      end.mutable_end();
      if (stream_->Write(end)) stream_->WritesDone();
      const grpc::Status status = CloseStream(/*cancel=*/false);
      if (published_) return *published_;
      if (!job_failure_.empty()) throw std::runtime_error(job_failure_);
      if (Refused(status.error_code())) throw std::runtime_error(Describe(status));
      // The link broke around MappingEnd: the job either waits (resume it and end it again) or
      // is already being published.
      if (!Resume()) {
        if (std::optional<v1::MappingProgress> done = PublishedMeanwhile()) return *done;
        throw std::runtime_error(failure_);
      }
    }
  }

  uint64_t job_id() const override { return job_id_; }

  MappingSessionStats stats() const override {
    std::lock_guard<std::mutex> lock(mutex_);
    return stats_;
  }

 private:
  v1::MappingRequest Request(const StereoFrame& frame) const {
    v1::MappingRequest request;
    v1::StereoFrame* out = request.mutable_frame();
    out->set_timestamp_ns(frame.timestamp_ns);
    out->set_left_encoded(frame.left_encoded.empty()
                              ? EncodeImage(frame.left, options_.encoding, options_.jpeg_quality)
                              : frame.left_encoded);
    out->set_right_encoded(frame.right_encoded.empty()
                               ? EncodeImage(frame.right, options_.encoding, options_.jpeg_quality)
                               : frame.right_encoded);
    for (const v1::ImuSample& s : frame.imu) *out->add_imu() = s;
    if (frame.odom_from_cam) *out->mutable_odom_from_cam() = *frame.odom_from_cam;
    return request;
  }

  // A new stream: the job's start (or its resumption), its first answer, and a reader thread.
  // On a resumption the unanswered frames after the last one mapped are sent again.
  bool OpenStream(bool resume, std::string* why) {
    channel_ = NewStreamChannel(options_.server, options_.credentials,
                                {std::chrono::milliseconds(10000), std::chrono::milliseconds(5000),
                                 options_.backoff_initial, options_.backoff_max});
    context_ = std::make_unique<grpc::ClientContext>();
    Authorize(context_.get(), options_.credentials);
    stream_ = v1::Mapping::NewStub(channel_)->BuildMap(context_.get());
    v1::MappingRequest start;
    v1::MappingStart* s = start.mutable_start();
    s->set_map_name(options_.map_name);
    s->set_robot_id(options_.robot_id);
    *s->mutable_rig() = options_.rig;
    *s->mutable_options() = options_.mapping;
    if (resume) s->set_resume_job_id(job_id_);
    v1::MappingProgress first;
    if (!stream_->Write(start) || !stream_->Read(&first)) {
      const grpc::Status status = stream_->Finish();
      stream_.reset();
      *why = "server " + options_.server + ": " + Describe(status);
      refused_ = Refused(status.error_code());
      return false;
    }
    job_id_ = first.job_id();
    std::vector<v1::MappingRequest> again;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stream_done_ = false;
      if (resume) {
        // Mapped already (their answers were lost with the old stream): not sent again.
        while (!unanswered_.empty() &&
               unanswered_.front().request.frame().timestamp_ns() <= first.timestamp_ns()) {
          unanswered_.pop_front();
        }
        for (const Pending& p : unanswered_) again.push_back(p.request);
      }
    }
    reader_ = std::thread([this, stream = stream_.get()] { Read(stream); });
    for (const v1::MappingRequest& request : again) {
      if (!stream_->Write(request)) {
        *why = "the link broke again while resuming";
        return false;
      }
    }
    return true;
  }

  void Read(Stream* stream) {
    v1::MappingProgress answer;
    while (stream->Read(&answer)) {
      std::lock_guard<std::mutex> lock(mutex_);
      const v1::MappingState state = answer.state();
      if (IsFrameAnswer(state)) {
        MappingAnswer taken{answer, 0.0};
        while (!unanswered_.empty() &&
               unanswered_.front().request.frame().timestamp_ns() <= answer.timestamp_ns()) {
          taken.latency_ms = std::chrono::duration<double, std::milli>(
                                 Clock::now() - unanswered_.front().submitted)
                                 .count();
          unanswered_.pop_front();
        }
        ++stats_.answered;
        stats_.lost += state == v1::MAPPING_LOST;
        stats_.frame_errors += state == v1::MAPPING_FRAME_ERROR;
        answers_.push_back(taken);
      }
      if (state == v1::MAPPING_PUBLISHED) published_ = answer;
      if (state == v1::MAPPING_FAILED)
        job_failure_ = "the server failed the job: " + answer.error();
      room_.notify_all();
    }
    std::lock_guard<std::mutex> lock(mutex_);
    stream_done_ = true;
    room_.notify_all();
  }

  // Ends the current stream (cancelled, or after the server's last answer) and its reader.
  grpc::Status CloseStream(bool cancel) {
    if (!stream_) return grpc::Status::OK;
    if (cancel) context_->TryCancel();
    if (reader_.joinable()) reader_.join();
    const grpc::Status status = stream_->Finish();
    stream_.reset();
    return status;
  }

  // Takes the job up again on a new stream, retrying with backoff for resume_timeout. Sets
  // failure_ and returns false when it cannot.
  bool Resume() {
    const grpc::Status broke = CloseStream(/*cancel=*/true);
    if (!job_failure_.empty()) {
      failure_ = job_failure_;
      return false;
    }
    const Clock::time_point deadline = Clock::now() + options_.resume_timeout;
    std::chrono::milliseconds backoff = options_.backoff_initial;
    std::string why = Describe(broke);
    while (Clock::now() < deadline) {
      std::this_thread::sleep_for(backoff);
      backoff = std::min(backoff * 2, options_.backoff_max);
      if (OpenStream(/*resume=*/true, &why)) {
        std::lock_guard<std::mutex> lock(mutex_);
        ++stats_.resumes;
        return true;
      }
      CloseStream(/*cancel=*/true);
      if (refused_) break;
    }
    failure_ = "the mapping stream of '" + options_.map_name +
               "' broke and could not be resumed (" + why + "): nothing was published";
    return false;
  }

  // After a break around MappingEnd: whether the server published the job anyway.
  std::optional<v1::MappingProgress> PublishedMeanwhile() const {
    grpc::ClientContext context;
    Authorize(&context, options_.credentials);
    context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(5));
    v1::ListJobsResponse jobs;
    if (!v1::Mapping::NewStub(channel_)->ListJobs(&context, {}, &jobs).ok()) return std::nullopt;
    for (const v1::MappingJob& job : jobs.jobs()) {
      if (job.job_id() != job_id_ || job.state() != v1::MAPPING_PUBLISHED) continue;
      v1::MappingProgress done;
      done.set_state(v1::MAPPING_PUBLISHED);
      done.set_job_id(job.job_id());
      done.set_frame_index(job.frames());
      done.set_keyframes(job.keyframes());
      done.set_points(job.points());
      done.mutable_map()->set_name(job.map_name());
      return done;
    }
    return std::nullopt;
  }

  const MappingSessionOptions options_;
  std::shared_ptr<grpc::Channel> channel_;
  std::unique_ptr<grpc::ClientContext> context_;
  std::unique_ptr<Stream> stream_;
  std::thread reader_;
  uint64_t job_id_ = 0;
  bool refused_ = false;
  std::string failure_;  // Why the session cannot go on (Submit and Finish report it).

  mutable std::mutex mutex_;  // Guards what follows (shared with the reader thread).
  std::condition_variable room_;
  std::deque<Pending> unanswered_;
  std::vector<MappingAnswer> answers_;
  bool stream_done_ = false;
  std::optional<v1::MappingProgress> published_;
  std::string job_failure_;
  MappingSessionStats stats_;
};

}  // namespace

std::unique_ptr<MappingSession> MappingSession::Open(const MappingSessionOptions& options) {
  options.Check();
  auto session = std::make_unique<MappingSessionImpl>(options);
  session->Start();
  return session;
}

}  // namespace visloc::client
