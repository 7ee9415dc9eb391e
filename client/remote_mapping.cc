#include "client/remote_mapping.h"

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <mutex>
#include <optional>
#include <thread>
#include <vector>

#include "client/outcome.h"
#include "core/util/check.h"
#include "core/util/strings.h"
#include "core/util/text_file.h"
#include "proto/mapping_convert.h"
#include "visloc/v1/visloc.grpc.pb.h"

namespace visloc::cli {

namespace {

using Clock = std::chrono::steady_clock;
using Stream = grpc::ClientReaderWriter<v1::MappingRequest, v1::MappingProgress>;

// What the server answered, shared between the sending and the receiving thread, across the
// streams of one job (a link that breaks is resumed on a new stream).
struct Answers {
  std::mutex mutex;
  std::condition_variable changed;
  uint64_t answered_here = 0;  // Frame answers on this stream.
  uint64_t job_id = 0;
  int lost = 0, frame_errors = 0;
  std::string first_frame_error;
  bool done = false;                    // The server closed this stream.
  std::vector<Clock::time_point> sent;  // Per frame, when it was last written.
  std::vector<double> latency_ms;       // Per answered frame: from writing it to its answer.
  std::optional<v1::MappingProgress> published;
  std::string failure;
};

const char* StateName(v1::MappingState state) {
  switch (state) {
    case v1::MAPPING_TRACKING:
      return "tracking";
    case v1::MAPPING_LOST:
      return "lost";
    case v1::MAPPING_FRAME_ERROR:
      return "bad frame";
    case v1::MAPPING_FINISHING:
      return "global bundle adjustment, visibility learning, vocabulary";
    case v1::MAPPING_PUBLISHED:
      return "published";
    case v1::MAPPING_FAILED:
      return "failed";
    case v1::MAPPING_RESUMED:
      return "resumed";
    default:
      return "?";
  }
}

bool IsFrameAnswer(v1::MappingState state) {
  return state == v1::MAPPING_TRACKING || state == v1::MAPPING_LOST ||
         state == v1::MAPPING_FRAME_ERROR;
}

void ReadAnswers(Stream* stream, size_t total, bool progress, Answers* answers) {
  v1::MappingProgress answer;
  while (stream->Read(&answer)) {
    std::lock_guard<std::mutex> lock(answers->mutex);
    const v1::MappingState state = answer.state();
    if (answer.job_id() != 0) answers->job_id = answer.job_id();
    if (IsFrameAnswer(state)) {
      ++answers->answered_here;
      answers->lost += state == v1::MAPPING_LOST;
      if (state == v1::MAPPING_FRAME_ERROR && answers->frame_errors++ == 0) {
        answers->first_frame_error = StrCat("frame ", answer.frame_index(), ": ", answer.error());
      }
      if (answer.frame_index() < answers->sent.size()) {
        answers->latency_ms.push_back(std::chrono::duration<double, std::milli>(
                                          Clock::now() - answers->sent[answer.frame_index()])
                                          .count());
      }
    }
    if (state == v1::MAPPING_PUBLISHED) answers->published = answer;
    if (state == v1::MAPPING_FAILED) answers->failure = answer.error();
    if (progress) {
      std::fprintf(stderr, "\r\33[Kframe %llu / %zu: %s, %u keyframes, %llu points",
                   static_cast<unsigned long long>(answer.frame_index() + 1), total,
                   StateName(state), answer.keyframes(),
                   static_cast<unsigned long long>(answer.points()));
    }
    answers->changed.notify_all();
  }
  std::lock_guard<std::mutex> lock(answers->mutex);
  answers->done = true;
  answers->changed.notify_all();
}

v1::MappingStart StartOf(const Dataset& dataset, const RemoteBuildOptions& options) {
  if (!dataset.has_stereo()) {
    throw InputError(StrCat(dataset.root, ": map building needs a stereo dataset (no cam1)"));
  }
  v1::MappingStart start;
  start.set_map_name(options.name);
  start.set_robot_id(options.robot_id);
  *start.mutable_options() = options.wire;
  proto::ToProto(dataset.left.camera, dataset.right->camera, dataset.left.body_from_cam,
                 dataset.right->body_from_cam, start.mutable_rig());
  return start;
}

// When frame `index` is due: at `rate_hz`, at the recording's own pace (0), or now (negative).
Clock::time_point DueTime(const Dataset& dataset, size_t index, double rate_hz,
                          Clock::time_point start) {
  if (rate_hz < 0) return Clock::now();
  const double seconds =
      rate_hz > 0 ? index / rate_hz
                  : (dataset.frames[index].timestamp_ns - dataset.frames[0].timestamp_ns) * 1e-9;
  return start +
         std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds));
}

// Codes after which a job cannot go on: the server said no, or the job is gone.
bool IsRefusal(grpc::StatusCode code) {
  return code == grpc::StatusCode::INVALID_ARGUMENT || code == grpc::StatusCode::ALREADY_EXISTS ||
         code == grpc::StatusCode::PERMISSION_DENIED || code == grpc::StatusCode::UNAUTHENTICATED ||
         code == grpc::StatusCode::NOT_FOUND || code == grpc::StatusCode::RESOURCE_EXHAUSTED ||
         code == grpc::StatusCode::FAILED_PRECONDITION || code == grpc::StatusCode::UNIMPLEMENTED;
}

// One recording streamed to one job, over as many streams as cuts of the link need.
class MappingUpload {
 public:
  MappingUpload(const Connection& server, const Dataset& dataset, const RemoteBuildOptions& options)
      : server_(server), dataset_(dataset), options_(options), start_(StartOf(dataset, options)) {
    answers_.sent.resize(dataset.frames.size());
  }

  // Streams until the map is published; throws InputError when it is refused or the link stays
  // down beyond options.resume_s.
  void Run() {
    started_ = Clock::now();
    Clock::time_point down_since{};
    for (int attempt = 0;; ++attempt) {
      const grpc::Status status = Attempt();
      if (answers_.published) return;
      if (!answers_.failure.empty() || IsRefusal(status.error_code())) {
        CheckCall(status.ok() ? grpc::Status(grpc::StatusCode::UNKNOWN, answers_.failure) : status,
                  server_.server);
      }
      // The link (or the server) went away mid-run.
      if (down_since == Clock::time_point{}) down_since = Clock::now();
      const double down_s = std::chrono::duration<double>(Clock::now() - down_since).count();
      if (answers_.job_id == 0 || down_s > options_.resume_s) {
        throw InputError(StrCat("server ", server_.server, ": the mapping stream broke after ",
                                next_, " of ", dataset_.frames.size(), " frames were sent (",
                                status.error_message(), ", gRPC code ", status.error_code(),
                                "): nothing was published; run the build again"));
      }
      std::this_thread::sleep_for(
          std::chrono::milliseconds(std::min(250 << std::min(attempt, 3), 2000)));
      if (Resumed()) down_since = {};
    }
  }

  int Report() {
    const v1::MappingProgress& done = *answers_.published;
    std::vector<double>& latency = answers_.latency_ms;
    std::sort(latency.begin(), latency.end());
    const double median_ms = latency.empty() ? 0.0 : latency[latency.size() / 2];
    const double max_ms = latency.empty() ? 0.0 : latency.back();
    const double sending_s = std::chrono::duration<double>(sent_all_ - started_).count();
    const double rate = done.frame_index() / std::max(sending_s, 1e-9);
    std::string sentence =
        StrCat("built '", options_.name, "' on ", server_.server, " from ", done.frame_index(),
               " stereo frames: ", done.keyframes(), " keyframes, ", done.points(), " points");
    if (answers_.lost > 0) sentence += StrCat("; tracking failed on ", answers_.lost, " frames");
    if (answers_.frame_errors > 0) {
      sentence +=
          StrCat("; ", answers_.frame_errors, " frames refused (", answers_.first_frame_error, ")");
    }
    if (resumes_ > 0)
      sentence += StrCat("; the link broke and the job was resumed ", resumes_,
                         resumes_ == 1 ? " time" : " times");
    sentence +=
        StrCat("; mapped at ", FormatFixed(rate, 1), " frames a second, each answered in ",
               FormatFixed(median_ms, 0), " ms (median), ", FormatFixed(max_ms, 0), " ms at most");
    const double paced_hz = PacedRate();
    if (paced_hz > 0 && rate < 0.95 * paced_hz) {
      sentence += StrCat("; FELL BEHIND the ", FormatFixed(paced_hz, 1),
                         " frames a second it was paced at (the link's bandwidth or the server's "
                         "time per frame: see each answer's time)");
    }
    return PrintOutcome(options_.json, sentence,
                        {{"map", options_.name},
                         {"server", server_.server},
                         {"job", static_cast<int64_t>(answers_.job_id)},
                         {"frames", static_cast<int64_t>(done.frame_index())},
                         {"keyframes", static_cast<int64_t>(done.keyframes())},
                         {"points", static_cast<int64_t>(done.points())},
                         {"lost_frames", static_cast<int64_t>(answers_.lost)},
                         {"refused_frames", static_cast<int64_t>(answers_.frame_errors)},
                         {"resumes", static_cast<int64_t>(resumes_)},
                         {"frames_per_second", rate},
                         {"paced_frames_per_second", PacedRate()},
                         {"answer_ms_median", median_ms},
                         {"answer_ms_max", max_ms},
                         {"finish_ms", done.frame_ms()}});
  }

 private:
  // Opens a stream to the job (a new one, or the one to resume), sends the frames from next_ on,
  // then MappingEnd; returns the stream's status.
  grpc::Status Attempt() {
    auto stub = v1::Mapping::NewStub(server_.OpenChannel());
    grpc::ClientContext context;
    server_.Prepare(&context);
    std::unique_ptr<Stream> stream = stub->BuildMap(&context);
    v1::MappingRequest request;
    *request.mutable_start() = start_;
    request.mutable_start()->set_resume_job_id(answers_.job_id);
    bool link_ok = stream->Write(request);
    if (link_ok && answers_.job_id != 0 && !AwaitResumed(stream.get())) link_ok = false;
    {
      std::lock_guard<std::mutex> lock(answers_.mutex);
      answers_.answered_here = 0;
      answers_.done = false;
    }
    std::thread reader(ReadAnswers, stream.get(), dataset_.frames.size(), options_.progress,
                       &answers_);
    for (uint64_t sent_here = 0; link_ok && next_ < dataset_.frames.size(); ++sent_here) {
      {
        std::unique_lock<std::mutex> lock(answers_.mutex);
        answers_.changed.wait(lock, [&] {
          return answers_.done ||
                 sent_here - answers_.answered_here < static_cast<uint64_t>(options_.max_in_flight);
        });
        if (answers_.done) break;
      }
      std::this_thread::sleep_until(DueTime(dataset_, next_, options_.rate_hz, started_));
      link_ok = SendFrame(stream.get(), next_);
      if (link_ok) ++next_;
    }
    if (link_ok) {
      sent_all_ = Clock::now();
      request.Clear();
      request.mutable_end();
      stream->Write(request);
    }
    stream->WritesDone();
    reader.join();
    if (options_.progress) std::fprintf(stderr, "\r\33[K");
    return stream->Finish();
  }

  // The rate frames were paced at (--rate, or the recording's own); 0 when sent as fast as
  // the server answered.
  double PacedRate() const {
    if (options_.rate_hz > 0) return options_.rate_hz;
    const auto& frames = dataset_.frames;
    if (options_.rate_hz < 0 || frames.size() < 2) return 0.0;
    return (frames.size() - 1) /
           ((frames.back().timestamp_ns - frames.front().timestamp_ns) * 1e-9);
  }

  bool SendFrame(Stream* stream, size_t index) {
    v1::MappingRequest request;
    v1::StereoFrame* frame = request.mutable_frame();
    frame->set_timestamp_ns(dataset_.frames[index].timestamp_ns);
    frame->set_left_encoded(ReadFileBytes(dataset_.frames[index].left_path));
    frame->set_right_encoded(ReadFileBytes(dataset_.frames[index].right_path));
    {
      std::lock_guard<std::mutex> lock(answers_.mutex);
      answers_.sent[index] = Clock::now();
    }
    return stream->Write(request);
  }

  // A resumed job's first answer says the last frame it mapped: frames resume after it (those
  // sent but lost on the way are sent again; those mapped whose answers were lost are not).
  bool AwaitResumed(Stream* stream) {
    v1::MappingProgress resumed;
    if (!stream->Read(&resumed) || resumed.state() != v1::MAPPING_RESUMED) return false;
    const auto& frames = dataset_.frames;
    next_ = std::upper_bound(frames.begin(), frames.end(), resumed.timestamp_ns(),
                             [](int64_t t, const FrameRecord& f) { return t < f.timestamp_ns; }) -
            frames.begin();
    resumed_ = true;
    ++resumes_;
    return true;
  }

  bool Resumed() {
    const bool resumed = resumed_;
    resumed_ = false;
    return resumed;
  }

  const Connection& server_;
  const Dataset& dataset_;
  const RemoteBuildOptions& options_;
  const v1::MappingStart start_;
  Answers answers_;
  size_t next_ = 0;  // The next frame to send.
  int resumes_ = 0;
  bool resumed_ = false;
  Clock::time_point started_, sent_all_;
};

}  // namespace

int RemoteMapBuild(const Connection& server, const Dataset& dataset,
                   const RemoteBuildOptions& options) {
  VISLOC_CHECK(options.max_in_flight >= 1, "max_in_flight ", options.max_in_flight);
  if (dataset.frames.empty()) throw InputError(StrCat(dataset.root, ": no frames to map"));
  MappingUpload upload(server, dataset, options);
  upload.Run();
  return upload.Report();
}

}  // namespace visloc::cli
