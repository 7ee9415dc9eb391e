#include "client/remote_mapping.h"

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <mutex>
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

// What the server answered so far, shared between the sending and the receiving thread.
struct Answers {
  std::mutex mutex;
  std::condition_variable changed;
  uint64_t answered = 0;  // Frame answers.
  int lost = 0, frame_errors = 0;
  std::string first_frame_error;
  bool done = false;                    // The server closed its side.
  std::vector<Clock::time_point> sent;  // Per frame, when it was written.
  std::vector<double> latency_ms;       // Per answered frame: from writing it to its answer.
  v1::MappingProgress last;
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
    default:
      return "?";
  }
}

void ReadAnswers(grpc::ClientReaderWriter<v1::MappingRequest, v1::MappingProgress>* stream,
                 size_t total, bool progress, Answers* answers) {
  v1::MappingProgress answer;
  while (stream->Read(&answer)) {
    std::lock_guard<std::mutex> lock(answers->mutex);
    const v1::MappingState state = answer.state();
    if (state == v1::MAPPING_TRACKING || state == v1::MAPPING_LOST ||
        state == v1::MAPPING_FRAME_ERROR) {
      ++answers->answered;
      answers->lost += state == v1::MAPPING_LOST;
      if (answer.frame_index() < answers->sent.size()) {
        answers->latency_ms.push_back(std::chrono::duration<double, std::milli>(
                                          Clock::now() - answers->sent[answer.frame_index()])
                                          .count());
      }
      if (state == v1::MAPPING_FRAME_ERROR && answers->frame_errors++ == 0) {
        answers->first_frame_error = StrCat("frame ", answer.frame_index(), ": ", answer.error());
      }
    }
    if (state == v1::MAPPING_PUBLISHED) answers->published = answer;
    if (state == v1::MAPPING_FAILED) answers->failure = answer.error();
    if (progress) {
      std::fprintf(stderr, "\r\33[Kframe %llu / %zu: %s, %u keyframes, %llu points",
                   static_cast<unsigned long long>(answers->answered), total, StateName(state),
                   answer.keyframes(), static_cast<unsigned long long>(answer.points()));
    }
    answers->last = answer;
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

}  // namespace

int RemoteMapBuild(const Connection& server, const Dataset& dataset,
                   const RemoteBuildOptions& options) {
  VISLOC_CHECK(options.max_in_flight >= 1, "max_in_flight ", options.max_in_flight);
  const size_t total = dataset.frames.size();
  if (total == 0) throw InputError(StrCat(dataset.root, ": no frames to map"));
  v1::MappingRequest request;
  *request.mutable_start() = StartOf(dataset, options);
  auto stub = v1::Mapping::NewStub(server.OpenChannel());
  grpc::ClientContext context;
  server.Prepare(&context);
  auto stream = stub->BuildMap(&context);
  Answers answers;
  answers.sent.resize(total);
  std::thread reader(ReadAnswers, stream.get(), total, options.progress, &answers);
  bool link_ok = stream->Write(request);
  const Clock::time_point started = Clock::now();
  for (size_t i = 0; link_ok && i < total; ++i) {
    {
      std::unique_lock<std::mutex> lock(answers.mutex);
      answers.changed.wait(lock, [&] {
        return answers.done || i - answers.answered < static_cast<uint64_t>(options.max_in_flight);
      });
      if (answers.done) break;
    }
    std::this_thread::sleep_until(DueTime(dataset, i, options.rate_hz, started));
    request.Clear();
    v1::StereoFrame* frame = request.mutable_frame();
    frame->set_timestamp_ns(dataset.frames[i].timestamp_ns);
    frame->set_left_encoded(ReadFileBytes(dataset.frames[i].left_path));
    frame->set_right_encoded(ReadFileBytes(dataset.frames[i].right_path));
    {
      std::lock_guard<std::mutex> lock(answers.mutex);
      answers.sent[i] = Clock::now();
    }
    link_ok = stream->Write(request);
  }
  const double sending_s = std::chrono::duration<double>(Clock::now() - started).count();
  if (link_ok) {
    request.Clear();
    request.mutable_end();
    stream->Write(request);
  }
  stream->WritesDone();
  reader.join();
  if (options.progress) std::fprintf(stderr, "\r\33[K");
  const grpc::Status status = stream->Finish();
  if (!answers.published) {
    if (!answers.failure.empty() || status.error_code() == grpc::StatusCode::INVALID_ARGUMENT ||
        status.error_code() == grpc::StatusCode::ALREADY_EXISTS ||
        status.error_code() == grpc::StatusCode::PERMISSION_DENIED ||
        status.error_code() == grpc::StatusCode::UNAUTHENTICATED) {
      CheckCall(status.ok() ? grpc::Status(grpc::StatusCode::UNKNOWN, answers.failure) : status,
                server.server);
    }
    // The link (or the server) went away mid-run: the server publishes nothing for it.
    throw InputError(StrCat("server ", server.server, ": the mapping stream broke after ",
                            answers.answered, " of ", total, " frames were mapped (",
                            status.error_message(), ", gRPC code ", status.error_code(),
                            "): nothing was published; run the build again"));
  }
  const v1::MappingProgress& done = *answers.published;
  const double rate = answers.answered / std::max(sending_s, 1e-9);
  std::string sentence =
      StrCat("built '", options.name, "' on ", server.server, " from ", answers.answered,
             " stereo frames: ", done.keyframes(), " keyframes, ", done.points(), " points");
  if (answers.lost > 0) sentence += StrCat("; tracking failed on ", answers.lost, " frames");
  if (answers.frame_errors > 0) {
    sentence +=
        StrCat("; ", answers.frame_errors, " frames refused (", answers.first_frame_error, ")");
  }
  std::vector<double>& latency = answers.latency_ms;
  std::sort(latency.begin(), latency.end());
  const double median_ms = latency.empty() ? 0.0 : latency[latency.size() / 2];
  const double max_ms = latency.empty() ? 0.0 : latency.back();
  sentence +=
      StrCat("; mapped at ", FormatFixed(rate, 1), " frames a second, each answered in ",
             FormatFixed(median_ms, 0), " ms (median), ", FormatFixed(max_ms, 0), " ms at most");
  return PrintOutcome(options.json, sentence,
                      {{"map", options.name},
                       {"server", server.server},
                       {"frames", static_cast<int64_t>(answers.answered)},
                       {"keyframes", static_cast<int64_t>(done.keyframes())},
                       {"points", static_cast<int64_t>(done.points())},
                       {"lost_frames", static_cast<int64_t>(answers.lost)},
                       {"refused_frames", static_cast<int64_t>(answers.frame_errors)},
                       {"frames_per_second", rate},
                       {"answer_ms_median", median_ms},
                       {"answer_ms_max", max_ms},
                       {"finish_ms", done.frame_ms()}});
}

}  // namespace visloc::cli
