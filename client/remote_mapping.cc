#include "client/remote_mapping.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <thread>
#include <vector>

#include "client/outcome.h"
#include "core/util/check.h"
#include "core/util/strings.h"
#include "core/util/text_file.h"
#include "proto/mapping_convert.h"
#include "visloc/client/mapping_session.h"

namespace visloc::cli {

namespace {

using Clock = std::chrono::steady_clock;

const char* StateName(v1::MappingState state) {
  switch (state) {
    case v1::MAPPING_TRACKING:
      return "tracking";
    case v1::MAPPING_LOST:
      return "lost";
    case v1::MAPPING_FRAME_ERROR:
      return "bad frame";
    default:
      return "?";
  }
}

client::MappingSessionOptions SessionOptions(const Connection& server, const Dataset& dataset,
                                             const RemoteBuildOptions& options) {
  if (!dataset.has_stereo()) {
    throw InputError(StrCat(dataset.root, ": map building needs a stereo dataset (no cam1)"));
  }
  client::MappingSessionOptions session;
  client::SessionOptions link;  // The target and trust every remote verb resolves the same way.
  server.ToLibrary(&link);
  session.server = link.server;
  session.credentials = link.credentials;
  session.map_name = options.name;
  session.robot_id = options.robot_id;
  session.mapping = options.wire;
  session.max_in_flight = options.max_in_flight;
  session.resume_timeout =
      std::chrono::milliseconds(static_cast<int64_t>(options.resume_s * 1000.0));
  proto::ToProto(dataset.left.camera, dataset.right->camera, dataset.left.body_from_cam,
                 dataset.right->body_from_cam, &session.rig);
  return session;
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

// The rate frames were paced at (--rate, or the recording's own); 0 when sent as fast as the
// server answered.
double PacedRate(const Dataset& dataset, double rate_hz) {
  if (rate_hz > 0) return rate_hz;
  const auto& frames = dataset.frames;
  if (rate_hz < 0 || frames.size() < 2) return 0.0;
  return (frames.size() - 1) / ((frames.back().timestamp_ns - frames.front().timestamp_ns) * 1e-9);
}

// What came back, as it comes: the progress line, the first refused frame, answer times.
struct Answers {
  std::vector<double> latency_ms;
  std::string first_frame_error;

  void Take(std::vector<client::MappingAnswer> answers, size_t total, bool progress) {
    for (const client::MappingAnswer& a : answers) {
      latency_ms.push_back(a.latency_ms);
      const v1::MappingProgress& p = a.progress;
      if (p.state() == v1::MAPPING_FRAME_ERROR && first_frame_error.empty()) {
        first_frame_error = StrCat("frame ", p.frame_index(), ": ", p.error());
      }
      if (progress) {
        std::fprintf(stderr, "\r\33[Kframe %llu / %zu: %s, %u keyframes, %llu points",
                     static_cast<unsigned long long>(p.frame_index() + 1), total,
                     StateName(p.state()), p.keyframes(),
                     static_cast<unsigned long long>(p.points()));
      }
    }
  }
};

}  // namespace

int RemoteMapBuild(const Connection& server, const Dataset& dataset,
                   const RemoteBuildOptions& options) {
  VISLOC_CHECK(options.max_in_flight >= 1, "max_in_flight ", options.max_in_flight);
  const size_t total = dataset.frames.size();
  if (total == 0) throw InputError(StrCat(dataset.root, ": no frames to map"));
  std::unique_ptr<client::MappingSession> session;
  try {
    session = client::MappingSession::Open(SessionOptions(server, dataset, options));
  } catch (const std::runtime_error& e) {
    throw InputError(e.what());
  }
  Answers answers;
  const Clock::time_point started = Clock::now();
  for (size_t i = 0; i < total; ++i) {
    std::this_thread::sleep_until(DueTime(dataset, i, options.rate_hz, started));
    client::StereoFrame frame;
    frame.timestamp_ns = dataset.frames[i].timestamp_ns;
    frame.left_encoded = ReadFileBytes(dataset.frames[i].left_path);
    frame.right_encoded = ReadFileBytes(dataset.frames[i].right_path);
    std::string why;
    if (!session->Submit(frame, &why)) {
      if (options.progress) std::fprintf(stderr, "\r\33[K");
      throw InputError(StrCat("server ", server.server, ": ", why, " (", i, " of ", total,
                              " frames sent); run the build again"));
    }
    answers.Take(session->TakeAnswers(), total, options.progress);
  }
  const double sending_s = std::chrono::duration<double>(Clock::now() - started).count();
  if (options.progress) std::fprintf(stderr, "\r\33[Kfinishing: global bundle adjustment, ...");
  v1::MappingProgress done;
  try {
    done = session->Finish();
  } catch (const std::runtime_error& e) {
    if (options.progress) std::fprintf(stderr, "\r\33[K");
    throw InputError(StrCat("server ", server.server, ": ", e.what()));
  }
  answers.Take(session->TakeAnswers(), total, false);
  if (options.progress) std::fprintf(stderr, "\r\33[K");

  const client::MappingSessionStats stats = session->stats();
  std::vector<double>& latency = answers.latency_ms;
  std::sort(latency.begin(), latency.end());
  const double median_ms = latency.empty() ? 0.0 : latency[latency.size() / 2];
  const double max_ms = latency.empty() ? 0.0 : latency.back();
  const double rate = done.frame_index() / std::max(sending_s, 1e-9);
  const double paced_hz = PacedRate(dataset, options.rate_hz);
  std::string sentence =
      StrCat("built '", options.name, "' on ", server.server, " from ", done.frame_index(),
             " stereo frames: ", done.keyframes(), " keyframes, ", done.points(), " points");
  if (stats.lost > 0) sentence += StrCat("; tracking failed on ", stats.lost, " frames");
  if (stats.frame_errors > 0) {
    sentence +=
        StrCat("; ", stats.frame_errors, " frames refused (", answers.first_frame_error, ")");
  }
  if (stats.resumes > 0) {
    sentence += StrCat("; the link broke and the job was resumed ", stats.resumes,
                       stats.resumes == 1 ? " time" : " times");
  }
  sentence +=
      StrCat("; mapped at ", FormatFixed(rate, 1), " frames a second, each answered in ",
             FormatFixed(median_ms, 0), " ms (median), ", FormatFixed(max_ms, 0), " ms at most");
  if (paced_hz > 0 && rate < 0.95 * paced_hz) {
    sentence += StrCat("; FELL BEHIND the ", FormatFixed(paced_hz, 1),
                       " frames a second it was paced at (the link's bandwidth or the server's "
                       "time per frame: see each answer's time)");
  }
  return PrintOutcome(options.json, sentence,
                      {{"map", options.name},
                       {"server", server.server},
                       {"job", static_cast<int64_t>(session->job_id())},
                       {"frames", static_cast<int64_t>(done.frame_index())},
                       {"keyframes", static_cast<int64_t>(done.keyframes())},
                       {"points", static_cast<int64_t>(done.points())},
                       {"lost_frames", static_cast<int64_t>(stats.lost)},
                       {"refused_frames", static_cast<int64_t>(stats.frame_errors)},
                       {"resumes", static_cast<int64_t>(stats.resumes)},
                       {"frames_per_second", rate},
                       {"paced_frames_per_second", paced_hz},
                       {"answer_ms_median", median_ms},
                       {"answer_ms_max", max_ms},
                       {"finish_ms", done.frame_ms()}});
}

}  // namespace visloc::cli
