#include "client/remote_mapping.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <thread>
#include <vector>

#include "client/outcome.h"
#include "client/video_source.h"
#include "core/util/check.h"
#include "core/util/strings.h"
#include "core/util/text_file.h"
#include "dataset/euroc.h"
#include "proto/mapping_convert.h"
#include "visloc/client/mapping_session.h"

namespace visloc::cli {

namespace {

using Clock = std::chrono::steady_clock;

// When frame `index` of a recording is due: at `rate_hz`, at its own pace (0), or now (negative).
Clock::time_point DueTime(const Dataset& dataset, size_t index, double rate_hz,
                          Clock::time_point start) {
  if (rate_hz < 0) return Clock::now();
  const double seconds =
      rate_hz > 0 ? index / rate_hz
                  : (dataset.frames[index].timestamp_ns - dataset.frames[0].timestamp_ns) * 1e-9;
  return start +
         std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds));
}

// A recorded run: the image files' own bytes, paced as asked.
class DatasetFeed final : public StereoFeed {
 public:
  DatasetFeed(const Dataset& dataset, double rate_hz) : dataset_(dataset), rate_hz_(rate_hz) {
    if (!dataset.has_stereo()) {
      throw InputError(StrCat(dataset.root, ": map building needs a stereo dataset (no cam1)"));
    }
    if (dataset.frames.empty()) throw InputError(StrCat(dataset.root, ": no frames to map"));
  }
  v1::StereoRig Rig() const override {
    v1::StereoRig rig;
    proto::ToProto(dataset_.left.camera, dataset_.right->camera, dataset_.left.body_from_cam,
                   dataset_.right->body_from_cam, &rig);
    return rig;
  }
  size_t expected() const override { return dataset_.frames.size(); }
  double paced_hz() const override {
    const auto& frames = dataset_.frames;
    if (rate_hz_ > 0) return rate_hz_;
    if (rate_hz_ < 0 || frames.size() < 2) return 0.0;
    return (frames.size() - 1) /
           ((frames.back().timestamp_ns - frames.front().timestamp_ns) * 1e-9);
  }
  bool Next(client::StereoFrame* frame) override {
    if (next_ >= dataset_.frames.size()) return false;
    const size_t i = next_++;
    std::this_thread::sleep_until(DueTime(dataset_, i, rate_hz_, start_));
    frame->timestamp_ns = dataset_.frames[i].timestamp_ns;
    frame->left_encoded = ReadFileBytes(dataset_.frames[i].left_path);
    frame->right_encoded = ReadFileBytes(dataset_.frames[i].right_path);
    return true;
  }

 private:
  const Dataset& dataset_;
  const double rate_hz_;
  size_t next_ = 0;
  const Clock::time_point start_ = Clock::now();
};

std::atomic<bool> interrupted{false};
void OnInterrupt(int) { interrupted = true; }

// Two cameras read through OpenCV, paired by grabbing both before decoding either; stamped with
// the clock (devices) or their position in the files. Ends at the files' end, after `frames`
// pairs, or on Ctrl-C (the run so far is then published).
class CameraFeed final : public StereoFeed {
 public:
  CameraFeed(const std::vector<std::string>& sources, const std::vector<std::string>& yamls,
             int frames, double rate_hz)
      : left_(sources.at(0), "--camera"),
        right_(sources.at(1), "--camera"),
        left_info_(ReadSensorYaml(yamls.at(0))),
        right_info_(ReadSensorYaml(yamls.at(1))),
        frames_(frames),
        rate_hz_(rate_hz) {
    std::signal(SIGINT, OnInterrupt);
  }
  ~CameraFeed() override { std::signal(SIGINT, SIG_DFL); }
  v1::StereoRig Rig() const override {
    v1::StereoRig rig;
    proto::ToProto(left_info_.camera, right_info_.camera, left_info_.body_from_cam,
                   right_info_.body_from_cam, &rig);
    return rig;
  }
  size_t expected() const override {
    const size_t in_files = std::min(left_.file_frames(), right_.file_frames());
    return frames_ > 0 ? (in_files ? std::min<size_t>(frames_, in_files) : frames_) : in_files;
  }
  double paced_hz() const override {
    return rate_hz_ > 0 ? rate_hz_ : left_.live() ? 0.0 : left_.file_fps();
  }
  bool Next(client::StereoFrame* frame) override {
    if (interrupted || (frames_ > 0 && read_ >= static_cast<size_t>(frames_))) return false;
    if (!left_.Grab() || !right_.Grab()) return false;
    if (!left_.Retrieve(&frame->left) || !right_.Retrieve(&frame->right)) return false;
    frame->timestamp_ns = left_.Stamp(read_++, paced_hz(), /*pace=*/true, start_);
    return true;
  }

 private:
  VideoSource left_, right_;
  CameraInfo left_info_, right_info_;
  const int frames_;
  const double rate_hz_;
  size_t read_ = 0;
  const Clock::time_point start_ = Clock::now();
};

client::MappingSessionOptions SessionOptions(const Connection& server, const v1::StereoRig& rig,
                                             const RemoteBuildOptions& options) {
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
  session.rig = rig;
  return session;
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
        std::fprintf(stderr, "\r\33[Kframe %llu%s: %s, %u keyframes, %llu points",
                     static_cast<unsigned long long>(p.frame_index() + 1),
                     total ? StrCat(" / ", total).c_str() : "",
                     proto::MappingStateText(p.state()).c_str(), p.keyframes(),
                     static_cast<unsigned long long>(p.points()));
      }
    }
  }
};

// What the run did, as a sentence or JSON.
int Report(const Connection& server, const RemoteBuildOptions& options,
           const client::MappingSession& session, const v1::MappingProgress& done, Answers* answers,
           double sending_s, double paced_hz) {
  const client::MappingSessionStats stats = session.stats();
  std::vector<double>& latency = answers->latency_ms;
  std::sort(latency.begin(), latency.end());
  const double median_ms = latency.empty() ? 0.0 : latency[latency.size() / 2];
  const double max_ms = latency.empty() ? 0.0 : latency.back();
  const double rate = done.frame_index() / std::max(sending_s, 1e-9);
  std::string sentence =
      StrCat("built '", options.name, "' on ", server.server, " from ", done.frame_index(),
             " stereo frames: ", done.keyframes(), " keyframes, ", done.points(), " points");
  if (stats.lost > 0) sentence += StrCat("; tracking failed on ", stats.lost, " frames");
  if (stats.frame_errors > 0) {
    sentence +=
        StrCat("; ", stats.frame_errors, " frames refused (", answers->first_frame_error, ")");
  }
  if (stats.resumes > 0) {
    sentence += StrCat("; the link broke and the job was resumed ", stats.resumes,
                       stats.resumes == 1 ? " time" : " times");
  }
  const v1::DisparityCorrection& correction = done.disparity_correction();
  if (correction.offset_px() != 0 || correction.right_camera_yaw_deg() != 0) {
    sentence += StrCat("; the rig's disparity correction ", FormatFixed(correction.offset_px(), 3),
                       " px, right camera turned ",
                       FormatFixed(correction.right_camera_yaw_deg(), 4), " deg");
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
                       {"job", static_cast<int64_t>(session.job_id())},
                       {"frames", static_cast<int64_t>(done.frame_index())},
                       {"keyframes", static_cast<int64_t>(done.keyframes())},
                       {"points", static_cast<int64_t>(done.points())},
                       {"disparity_offset_px", correction.offset_px()},
                       {"right_camera_yaw_deg", correction.right_camera_yaw_deg()},
                       {"lost_frames", static_cast<int64_t>(stats.lost)},
                       {"refused_frames", static_cast<int64_t>(stats.frame_errors)},
                       {"resumes", static_cast<int64_t>(stats.resumes)},
                       {"frames_per_second", rate},
                       {"paced_frames_per_second", paced_hz},
                       {"answer_ms_median", median_ms},
                       {"answer_ms_max", max_ms},
                       {"finish_ms", done.frame_ms()}});
}

}  // namespace

int StreamToMapper(const Connection& server, StereoFeed& feed, const RemoteBuildOptions& options) {
  VISLOC_CHECK(options.max_in_flight >= 1, "max_in_flight ", options.max_in_flight);
  std::unique_ptr<client::MappingSession> session;
  try {
    session = client::MappingSession::Open(SessionOptions(server, feed.Rig(), options));
  } catch (const std::runtime_error& e) {
    throw InputError(e.what());
  }
  const size_t total = feed.expected();
  Answers answers;
  const Clock::time_point started = Clock::now();
  size_t sent = 0;
  for (client::StereoFrame frame; feed.Next(&frame); frame = client::StereoFrame()) {
    std::string why;
    if (!session->Submit(frame, &why)) {
      if (options.progress) std::fprintf(stderr, "\r\33[K");
      throw InputError(StrCat("server ", server.server, ": ", why, " (", sent,
                              " frames sent); run the build again"));
    }
    ++sent;
    answers.Take(session->TakeAnswers(), total, options.progress);
  }
  const double sending_s = std::chrono::duration<double>(Clock::now() - started).count();
  if (sent == 0) throw InputError("no stereo frame was read: nothing to map");
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
  return Report(server, options, *session, done, &answers, sending_s, feed.paced_hz());
}

int RemoteMapBuild(const Connection& server, const Dataset& dataset,
                   const RemoteBuildOptions& options) {
  DatasetFeed feed(dataset, options.rate_hz);
  return StreamToMapper(server, feed, options);
}

int RemoteMapBuildFromCameras(const Connection& server, const std::vector<std::string>& sources,
                              const std::vector<std::string>& sensor_yamls, int frames,
                              const RemoteBuildOptions& options) {
  CameraFeed feed(sources, sensor_yamls, frames, options.rate_hz > 0 ? options.rate_hz : 0.0);
  return StreamToMapper(server, feed, options);
}

}  // namespace visloc::cli
