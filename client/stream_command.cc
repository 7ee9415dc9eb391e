// `visloc stream`: a robot's side of a localization session, through the client library
// (visloc::client). Reads a dataset and streams its left images (the files' bytes as they are,
// or re-encoded as the robot would: JPEG, PNG or raw), with odometry and gyro when asked, to
// visloc-server at the dataset's rate or as fast as possible. Writes and prints the same
// outputs as `visloc localize`, plus what the link did: client-side latency, frames dropped for
// a slow link, late answers, frames lost to broken streams, reconnections. The trajectory, the
// statistics and the event log are written as the answers arrive, so a run that ends badly
// keeps what was answered.

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <thread>

#include "client/commands.h"
#include "client/connection.h"
#include "client/dataset_frames.h"
#include "client/localization_report.h"
#include "client/video_source.h"
#include "core/eval/trajectory_eval.h"
#include "core/util/args.h"
#include "core/util/check.h"
#include "core/util/json.h"
#include "core/util/strings.h"
#include "core/util/text_file.h"
#include "dataset/dataset.h"
#include "dataset/euroc.h"
#include "dataset/tum.h"
#include "proto/convert.h"
#include "visloc/client/session.h"

namespace visloc::cli {
namespace {

namespace v1 = ::visloc::v1;
using Clock = std::chrono::steady_clock;

struct StreamArgs {
  Connection server;
  std::string map_name, dataset_dir, format, trajectory_path, stats_path, events_path, gt_path;
  // Live sources instead of a dataset: one per camera of the rig (the reference first), each
  // with its sensor.yaml.
  std::vector<std::string> camera_sources, sensor_paths;
  std::string robot_id = "visloc-stream";
  std::string frame = "map";  // Of the trajectory: map or site (the answers' site_from_cam).
  double rate_hz = -1.0;  // Negative: the dataset's timestamps; 0: as fast as possible.
  std::string policy = "all";
  std::string encoding;  // Empty: DefaultEncoding().
  int jpeg_quality = 90;
  int max_in_flight = 2, max_queued = 2;
  int frame_deadline_ms = 1000;
  int stall_timeout_ms = 0;  // 0: StallTimeout's default.
  bool odometry = false, json = false;
  int frames = 0;
  std::string cameras = "cam0";  // A dataset's rig (dataset_frames.h).
};

// A robot's pace (a live camera, the dataset's timing or a --rate) sends what a robot would:
// the client library's JPEG, so a recording streamed at 20 Hz meets the link as the robot
// would (a real 752x480 PNG is 210 KiB; at quality 90, about a quarter of that). A replay as
// fast as possible is an evaluation: the image files' own bytes, so nothing is lost.
std::string DefaultEncoding(const StreamArgs& args) {
  return args.camera_sources.empty() && args.rate_hz == 0 ? "file" : "jpeg";
}

// What the summary says of the encoding: "jpeg q90", "file", ...
std::string EncodingLabel(const StreamArgs& args) {
  return args.encoding == "jpeg" ? StrCat("jpeg q", args.jpeg_quality) : args.encoding;
}

// How long the stream may go without an answer before it is reopened: 2 s for a robot's pace;
// a minute for a replay as fast as possible, which promises every frame an answer however long
// the engine takes (a slow frame, say a relocalization under a sanitizer, is no stalled link,
// and reopening loses the frames on the wire; keepalive pings still find a dead connection).
std::chrono::milliseconds StallTimeout(const StreamArgs& args) {
  if (args.stall_timeout_ms > 0) return std::chrono::milliseconds(args.stall_timeout_ms);
  return args.rate_hz == 0 ? std::chrono::milliseconds(60000) : std::chrono::milliseconds(2000);
}

client::SessionOptions LibraryOptions(const StreamArgs& args, const CameraInfo& camera,
                                      const std::vector<v1::RigCamera>& rig_cameras) {
  client::SessionOptions o;
  args.server.ToLibrary(&o);
  o.map_name = args.map_name;
  o.robot_id = args.robot_id;
  proto::ToProto(camera.camera, &o.camera);
  o.session.set_drop_policy(args.policy == "newest" ? v1::NEWEST_ONLY : v1::PROCESS_ALL);
  if (args.odometry || !rig_cameras.empty()) {
    proto::ToProto(camera.body_from_cam, o.session.mutable_body_from_cam());
  }
  o.rig_cameras = rig_cameras;
  o.encoding = args.encoding == "png"   ? client::Encoding::kPng
               : args.encoding == "raw" ? client::Encoding::kRaw
                                        : client::Encoding::kJpeg;
  o.jpeg_quality = args.jpeg_quality;
  o.max_in_flight = args.max_in_flight;
  o.max_queued = args.max_queued;
  o.frame_deadline = std::chrono::milliseconds(args.frame_deadline_ms);
  o.stall_timeout = StallTimeout(args);
  if (args.rate_hz == 0) {
    // A replay as fast as possible: every frame is sent and answered however long it takes.
    o.wait_for_room = true;
    o.frame_deadline = std::chrono::hours(1);
  }
  // A command, unlike a robot, stops trying: a server unreachable this long ends the run.
  o.give_up_after = std::chrono::seconds(10);
  return o;
}

client::Frame LibraryFrame(const StreamArgs& args, const Dataset& dataset,
                           const std::vector<std::string>& cameras, size_t index) {
  const FrameInput input = DatasetFrameInput(dataset, index, args.odometry, args.odometry);
  v1::Frame wire;
  proto::ToProto(input, "", &wire);
  client::Frame frame;
  frame.timestamp_ns = input.timestamp_ns;
  if (wire.has_odom_from_cam()) frame.odom_from_cam = wire.odom_from_cam();
  frame.imu.assign(wire.imu().begin(), wire.imu().end());
  const std::string& path = dataset.frames[index].left_path;
  if (args.encoding == "file") {
    frame.encoded = ReadFileBytes(path);
  } else {
    frame.image = LoadGreyImage(path, dataset.left.camera.width(), dataset.left.camera.height());
  }
  for (size_t c = 1; c < cameras.size(); ++c) {
    client::RigFrameImage& rig_image = frame.rig_images.emplace_back();
    // The engine's tolerance by default: an image further off is none.
    const auto image =
        CameraImageAt(dataset, cameras[c], index, LocalizerOptions{}.max_rig_skew_ns);
    if (!image) continue;
    rig_image.timestamp_ns = image->first;
    if (args.encoding == "file") {
      rig_image.encoded = ReadFileBytes(image->second);
    } else {
      rig_image.image = LoadGreyImage(image->second, 0, 0);
    }
  }
  return frame;
}

// What came back, written as it arrives.
class StreamRecorder {
 public:
  // `dataset` (may be null: a live camera) names frames by their index in messages.
  StreamRecorder(const StreamArgs& args, const Dataset* dataset)
      : json_(args.json), site_frame_(args.frame == "site"), dataset_(dataset) {
    if (!args.trajectory_path.empty()) Open(&trajectory_, args.trajectory_path, TumHeader());
    if (!args.stats_path.empty()) Open(&stats_, args.stats_path, StatsCsvHeader() + "\n");
    if (!args.events_path.empty()) {
      Open(&events_, args.events_path,
           "wall_ms,event,timestamp_ns,latency_ms,status,source,relocalization,has_pose,"
           "inliers,link_state,detail\n");
    }
  }

  void Record(const client::Event& e, size_t frame_count) {
    using Kind = client::Event::Kind;
    const v1::LocalizeResponse& r = e.response;
    if (events_) {
      const bool answer = e.kind == Kind::kResult || e.kind == Kind::kLate;
      // Wall-clock milliseconds, so a test (or an operator) can line events up with the link.
      const int64_t wall_ms = std::chrono::duration_cast<std::chrono::milliseconds>(
                                  std::chrono::system_clock::now().time_since_epoch())
                                  .count();
      events_ << wall_ms << ',' << client::EventKindName(e.kind) << ',' << e.timestamp_ns << ','
              << FormatFixed(e.latency_ms, 2) << ',' << (answer ? v1::Status_Name(r.status()) : "")
              << ',' << (answer ? v1::PoseSource_Name(r.source()) : "") << ','
              << (answer ? r.relocalization().kind() : "") << ',' << (r.has_pose() ? 1 : 0) << ','
              << r.stats().inliers() << ','
              << (e.kind == Kind::kLinkState ? client::LinkStateName(e.link_state) : "") << ",\""
              << e.detail << "\"" << std::endl;
    }
    switch (e.kind) {
      case Kind::kResult:
        Answer(e, frame_count);
        break;
      case Kind::kLate:
        ++late;
        break;
      case Kind::kDropped:
        ++dropped;
        break;
      case Kind::kUndelivered:
        ++undelivered;
        break;
      case Kind::kLinkState:
        if (e.link_state == client::LinkState::kReconnecting) ++link_breaks;
        if (e.link_state == client::LinkState::kFailed) failure = e.detail;
        if (!json_) {
          std::fprintf(stderr, "%svisloc stream: link %s: %s\n", ShowProgress() ? "\n" : "",
                       client::LinkStateName(e.link_state), e.detail.c_str());
        }
        break;
    }
  }

  RunReport report;
  std::vector<double> latency_ms;
  // The server's own time per frame it answered with the engine (LocalizeResponse.timings.
  // server_ms: decoding, waiting for a worker and the engine, without the link); refused and
  // skipped frames, answered in microseconds, are left out.
  std::vector<double> server_ms;
  int errors = 0, skipped = 0, late = 0, dropped = 0, undelivered = 0, link_breaks = 0;
  std::string failure;

 private:
  static void Open(std::ofstream* out, const std::string& path, const std::string& header) {
    out->open(path, std::ios::trunc);
    if (!*out) throw InputError(path + ": cannot write");
    *out << header << std::flush;
  }

  void Answer(const client::Event& e, size_t frame_count) {
    const v1::LocalizeResponse& r = e.response;
    latency_ms.push_back(e.latency_ms);
    if (r.status() == v1::STATUS_ERROR) {
      ++errors;
      std::fprintf(stderr, "visloc stream: %s: server: %s\n", FrameName(e.timestamp_ns).c_str(),
                   r.error().c_str());
      return;
    }
    if (r.status() == v1::STATUS_SKIPPED) {
      // A reason means the server refused the frame (its rate limit), not the drop policy the
      // client chose: say so once.
      if (!r.error().empty() && skipped_reason_.empty()) {
        skipped_reason_ = r.error();
        std::fprintf(stderr, "visloc stream: %s skipped by the server: %s\n",
                     FrameName(e.timestamp_ns).c_str(), skipped_reason_.c_str());
      }
      ++skipped;
      return;
    }
    server_ms.push_back(r.timings().server_ms());
    LocalizationResult result = proto::FromProto(r);
    result.timestamp_ns = e.timestamp_ns;
    report.Add(result);
    if (trajectory_ && result.has_pose) {
      if (site_frame_ && !r.has_site_from_cam()) {
        throw InputError(
            "the server gave no site pose: the map records no up (write --frame "
            "map, or rebuild the map or tie it with map align)");
      }
      const Rigid3d pose =
          site_frame_ ? proto::FromProto(r.site_from_cam(), "site_from_cam") : result.map_from_cam;
      trajectory_ << TumLine({result.timestamp_ns, pose}) << std::flush;
    }
    if (stats_) stats_ << StatsCsvRow(result) << std::endl;
    if (ShowProgress() && !json_) {
      std::fprintf(stderr, "\r%-60s latency %6.1f ms", report.ProgressLine(frame_count).c_str(),
                   e.latency_ms);
    }
  }

  // "frame N" (the dataset index of the frame with this timestamp; timestamps increase
  // strictly), or "frame at T s" for a live camera.
  std::string FrameName(int64_t timestamp_ns) const {
    if (!dataset_) return StrCat("frame at ", FormatFixed(timestamp_ns * 1e-9, 3), " s");
    const auto it =
        std::lower_bound(dataset_->frames.begin(), dataset_->frames.end(), timestamp_ns,
                         [](const FrameRecord& f, int64_t t) { return f.timestamp_ns < t; });
    return StrCat("frame ", it - dataset_->frames.begin());
  }

  bool json_;
  bool site_frame_;  // The trajectory in the site frame.
  const Dataset* dataset_;
  std::ofstream trajectory_, stats_, events_;
  std::string skipped_reason_;
};

void ParseStreamArgs(const Args& raw_args, StreamArgs* args, bool* run) {
  ArgParser parser("visloc stream",
                   "Streams a dataset's left images to visloc-server as one robot session "
                   "through the client library, and reports every frame's answer: the TUM "
                   "trajectory, the per-frame statistics CSV, the link's event log, a live line "
                   "on a terminal, and a summary with the client-side latency.");
  args->server.AddFlags(parser);
  parser.AddFlag("map", &args->map_name, "map name on the server", true);
  parser.AddFlag("robot-id", &args->robot_id,
                 "the robot's name in the server's log and in visloc sessions");
  parser.AddFlag("dataset", &args->dataset_dir, "dataset folder (EuRoC or KITTI layout)");
  parser.AddList("camera", &args->camera_sources,
                 "instead of --dataset, a live source through OpenCV: a V4L2 device (/dev/video0 "
                 "or 0), a GStreamer pipeline (with '!'), or a video file; given again for a rig's "
                 "further cameras (--camera FRONT --camera REAR), their frames taken together");
  parser.AddList("camera-yaml", &args->sensor_paths,
                 "with --camera: each camera's model and T_BS (an EuRoC sensor.yaml, as `visloc "
                 "calibrate` writes), in the order of --camera");
  parser.AddFlag("format", &args->format, "euroc or kitti (default: detected)");
  parser.AddFlag("cameras", &args->cameras,
                 "with --dataset: the rig streamed, cam0 (the reference, reported) then others, "
                 "e.g. cam0,cam1 (the stereo pair) or cam0,cam2 (EuRoC's cam2 folder)");
  parser.AddFlag("rate", &args->rate_hz,
                 "frames per second to send (0: as fast as possible, every frame answered)");
  parser.SetDefaultText("rate", "the dataset's timing");
  parser.AddFlag("policy", &args->policy, "all (answer every frame) or newest (drop stale frames)");
  parser.AddFlag("encoding", &args->encoding,
                 "jpeg (the client library's), file (the image files' bytes), png or raw (grey "
                 "pixels)");
  parser.SetDefaultText("encoding", "jpeg at a robot's pace or from --camera; file with --rate 0");
  parser.AddFlag("jpeg-quality", &args->jpeg_quality, "1..100, with --encoding jpeg");
  parser.AddFlag("max-in-flight", &args->max_in_flight, "frames on the wire at once");
  parser.AddFlag("max-queued", &args->max_queued,
                 "frames waiting for the link; the oldest is dropped beyond this");
  parser.AddFlag("frame-deadline-ms", &args->frame_deadline_ms,
                 "frames waiting longer are dropped, answers later are reported late");
  parser.AddFlag("stall-timeout-ms", &args->stall_timeout_ms,
                 "no answer this long: the stream is reopened");
  parser.SetDefaultText("stall-timeout-ms", "2000; 60000 with --rate 0");
  parser.AddSwitch("odometry", &args->odometry, "send the dataset's odometry and gyro");
  parser.AddFlag("trajectory", &args->trajectory_path, "write the estimated poses (TUM)");
  parser.AddFlag("frame", &args->frame,
                 "the trajectory's frame: map (the first camera's) or site (z up: the frame map "
                 "align tied the map to, else its level frame; a map that knows up)");
  parser.AddFlag("stats", &args->stats_path, "write per-frame statistics (CSV)");
  parser.AddFlag("events", &args->events_path,
                 "write every answer, drop and link change as it happens (CSV)");
  parser.AddFlag("gt", &args->gt_path, "ground truth (TUM, map frame) for the summary");
  parser.AddFlag("frames", &args->frames, "stop after this many frames (0: all)");
  parser.AddSwitch("json", &args->json, "print the summary as one JSON object");
  *run = parser.Parse(raw_args, std::cout);
  if (!*run) return;
  args->server.ApplyEnvironment();
  if (!args->dataset_dir.empty() && !args->camera_sources.empty()) {
    throw UsageError("give --dataset DIR or --camera SOURCE, not both");
  }
  if (args->dataset_dir.empty() && args->camera_sources.empty()) {
    throw UsageError("give --dataset DIR or --camera SOURCE (with --camera-yaml sensor.yaml)");
  }
  if (!args->camera_sources.empty()) {
    if (args->sensor_paths.empty()) throw UsageError("--camera needs --camera-yaml sensor.yaml");
    if (args->sensor_paths.size() != args->camera_sources.size()) {
      throw UsageError("each --camera needs its --camera-yaml, in the same order");
    }
    if (args->camera_sources.size() > CameraRig::kMaxCameras) {
      throw UsageError(StrCat("--camera: at most ", CameraRig::kMaxCameras, " cameras"));
    }
    if (args->odometry) throw UsageError("--odometry comes from a dataset, not --camera");
    if (args->encoding == "file") {
      throw UsageError("--encoding file needs --dataset (a camera's frames are pixels)");
    }
    if (args->cameras != "cam0") throw UsageError("--cameras names a dataset's cameras");
  }
  if (args->encoding.empty()) args->encoding = DefaultEncoding(*args);
  if (args->rate_hz > 1000)
    throw UsageError("--rate must be at most 1000 Hz (0: as fast as possible)");
  if (args->stall_timeout_ms < 0)
    throw UsageError("--stall-timeout-ms must not be negative (0: the default)");
  if (args->policy != "all" && args->policy != "newest")
    throw UsageError("--policy is all or newest");
  if (args->frame != "map" && args->frame != "site") {
    throw UsageError("--frame must be map or site, not '" + args->frame + "'");
  }
  if (args->encoding != "file" && args->encoding != "jpeg" && args->encoding != "png" &&
      args->encoding != "raw") {
    throw UsageError("--encoding is file, jpeg, png or raw");
  }
}

void PrintStreamSummary(const StreamArgs& args, const StreamRecorder& rec,
                        const client::SessionStats& stats, size_t count, const Trajectory* gt) {
  const ErrorStats latency = ComputeErrorStats(rec.latency_ms);
  const double p99 = LatencyPercentile(rec.latency_ms, 0.99);
  const ErrorStats server = ComputeErrorStats(rec.server_ms);
  const double kb_per_frame = stats.sent ? stats.bytes_sent / 1024.0 / stats.sent : 0.0;
  if (args.json) {
    JsonWriter json;
    json.BeginObject().Field("server", args.server.server).Field("map", args.map_name);
    json.Field("errors", static_cast<int64_t>(rec.errors))
        .Field("skipped", static_cast<int64_t>(rec.skipped))
        .Field("late", static_cast<int64_t>(rec.late))
        .Field("dropped", static_cast<int64_t>(rec.dropped))
        .Field("undelivered", static_cast<int64_t>(rec.undelivered))
        .Field("link_breaks", static_cast<int64_t>(rec.link_breaks))
        .Field("streams_opened", static_cast<int64_t>(stats.streams_opened))
        .Field("encoding", EncodingLabel(args))
        .Field("kb_per_frame", kb_per_frame);
    json.Field("latency_ms_mean", latency.mean)
        .Field("latency_ms_p50", latency.median)
        .Field("latency_ms_p99", p99)
        .Field("server_ms_p50", server.median);
    rec.report.WriteSummaryJson(json, gt);
    json.EndObject();
    std::cout << json.str() << "\n";
    return;
  }
  std::printf("server %s, map %s: %zu frames, %d errors, %d skipped\n", args.server.server.c_str(),
              args.map_name.c_str(), count, rec.errors, rec.skipped);
  rec.report.PrintSummary(stdout, gt);
  std::printf(
      "latency (client, submit to answer): mean %.2f ms, p50 %.2f ms, p99 %.2f ms; the "
      "server's own p50 %.2f ms\n",
      latency.mean, latency.median, p99, server.median);
  std::printf(
      "link: %s, %.1f KiB a frame; %d dropped (link slower than the camera), %d late, %d "
      "undelivered, %d breaks, %llu streams\n",
      EncodingLabel(args).c_str(), kb_per_frame, rec.dropped, rec.late, rec.undelivered,
      rec.link_breaks, static_cast<unsigned long long>(stats.streams_opened));
}

// Where the frames come from: a dataset's files, or a live source through OpenCV.
class FrameSource {
 public:
  virtual ~FrameSource() = default;
  virtual const CameraInfo& camera() const = 0;
  virtual const Dataset* dataset() const { return nullptr; }
  // A rig's other cameras (none for one camera).
  virtual std::vector<v1::RigCamera> rig_cameras() const { return {}; }
  // Frames expected (for progress; 0: unknown).
  virtual size_t expected() const = 0;
  // The next frame, paced as the source runs; false at the end. Throws InputError for one bad
  // frame (the caller reports and skips it).
  virtual bool Next(client::Frame* frame) = 0;
};

class DatasetSource final : public FrameSource {
 public:
  explicit DatasetSource(const StreamArgs& args)
      : args_(args),
        dataset_(ReadQueryDataset(args.dataset_dir, args.format, args.odometry)),
        cameras_(ParseCameraNames(args.cameras)) {
    count_ = args.frames > 0 ? std::min<size_t>(args.frames, dataset_.frames.size())
                             : dataset_.frames.size();
    DatasetCameraRig(dataset_, cameras_, false);  // Throws for a camera the dataset lacks.
  }
  const CameraInfo& camera() const override { return dataset_.left; }
  std::vector<v1::RigCamera> rig_cameras() const override {
    return WireRigCameras(DatasetCameraRig(dataset_, cameras_, /*gyro=*/false), cameras_);
  }
  const Dataset* dataset() const override { return &dataset_; }
  size_t expected() const override { return count_; }
  bool Next(client::Frame* frame) override {
    if (next_ >= count_) return false;
    const size_t i = next_++;
    if (args_.rate_hz < 0) {
      std::this_thread::sleep_until(start_ +
                                    std::chrono::nanoseconds(dataset_.frames[i].timestamp_ns -
                                                             dataset_.frames.front().timestamp_ns));
    } else if (args_.rate_hz > 0) {
      std::this_thread::sleep_until(
          start_ + std::chrono::nanoseconds(static_cast<int64_t>(i * 1e9 / args_.rate_hz)));
    }
    *frame = LibraryFrame(args_, dataset_, cameras_, i);
    return true;
  }

 private:
  const StreamArgs& args_;
  Dataset dataset_;
  std::vector<std::string> cameras_;
  size_t count_ = 0, next_ = 0;
  Clock::time_point start_ = Clock::now();
};

// A V4L2 device ("/dev/video0" or "0"), a GStreamer pipeline (anything with a "!"), or a video
// file, read through OpenCV's VideoCapture; the camera model comes from a sensor.yaml. Frames
// are stamped with the clock when read (a device), or with their position in the file (paced
// at the file's frame rate, or --rate). A rig's further cameras are read beside it: every
// camera's frame grabbed first, then decoded, so they are taken as close together as the
// devices allow, and sent with the reference frame's stamp.
class CaptureSource final : public FrameSource {
 public:
  explicit CaptureSource(const StreamArgs& args) : args_(args) {
    for (size_t c = 0; c < args.camera_sources.size(); ++c) {
      cameras_.push_back(ReadSensorYaml(args.sensor_paths[c]));
      videos_.push_back(std::make_unique<VideoSource>(args.camera_sources[c], "--camera"));
    }
  }
  const CameraInfo& camera() const override { return cameras_.front(); }
  std::vector<v1::RigCamera> rig_cameras() const override {
    CameraRig rig;
    for (const CameraInfo& camera : cameras_) {
      rig.cameras.push_back(camera.camera);
      rig.body_from_cam.push_back(camera.body_from_cam);
    }
    return WireRigCameras(rig, args_.camera_sources);
  }
  size_t expected() const override {
    const size_t in_file = videos_.front()->file_frames();
    return args_.frames > 0 ? (in_file ? std::min<size_t>(args_.frames, in_file) : args_.frames)
                            : in_file;
  }
  bool Next(client::Frame* frame) override {
    if (args_.frames > 0 && read_ >= static_cast<size_t>(args_.frames)) return false;
    for (const auto& video : videos_) {
      if (!video->Grab()) return false;
    }
    std::vector<cv::Mat> images(videos_.size());
    for (size_t c = 0; c < videos_.size(); ++c) {
      if (!videos_[c]->Retrieve(&images[c])) return false;
    }
    const size_t i = read_++;
    const double rate = args_.rate_hz > 0 ? args_.rate_hz : videos_.front()->file_fps();
    *frame = client::Frame();
    frame->timestamp_ns = videos_.front()->Stamp(i, rate, /*pace=*/args_.rate_hz != 0, start_);
    frame->image = images[0];  // Grey or BGR; the library converts and checks the size.
    for (size_t c = 1; c < images.size(); ++c) {
      frame->rig_images.push_back({frame->timestamp_ns, images[c], ""});
    }
    return true;
  }

 private:
  const StreamArgs& args_;
  std::vector<CameraInfo> cameras_;
  std::vector<std::unique_ptr<VideoSource>> videos_;
  size_t read_ = 0;
  Clock::time_point start_ = Clock::now();
};

}  // namespace

int RunStream(const Args& raw_args) {
  StreamArgs args;
  bool run = false;
  ParseStreamArgs(raw_args, &args, &run);
  if (!run) return 0;
  std::unique_ptr<FrameSource> source;
  if (args.camera_sources.empty()) {
    source = std::make_unique<DatasetSource>(args);
  } else {
    source = std::make_unique<CaptureSource>(args);
  }
  const Trajectory ground_truth = args.gt_path.empty() ? Trajectory{} : ReadTum(args.gt_path);
  const size_t expected = source->expected();
  StreamRecorder recorder(args, source->dataset());
  std::mutex recorder_mutex;
  client::SessionOptions options = LibraryOptions(args, source->camera(), source->rig_cameras());
  options.on_event = [&](const client::Event& e) {
    std::lock_guard<std::mutex> lock(recorder_mutex);
    recorder.Record(e, expected);
  };
  CheckFlags(options);
  std::unique_ptr<client::Session> session = client::Session::Open(options);

  size_t count = 0;
  while (session->link_state() != client::LinkState::kFailed) {
    client::Frame frame;
    const size_t i = count;
    try {
      if (!source->Next(&frame)) break;
      ++count;
    } catch (const InputError& e) {
      ++count;
      std::fprintf(stderr, "visloc stream: frame %zu: %s (not sent)\n", i, e.what());
      continue;
    }
    std::string why_not;
    if (!session->Submit(frame, &why_not) && session->link_state() != client::LinkState::kFailed) {
      std::fprintf(stderr, "visloc stream: frame %zu: %s (not sent)\n", i, why_not.c_str());
    }
  }
  const client::LinkState final_state = session->link_state();
  session->Close(args.rate_hz == 0 ? std::chrono::milliseconds(600000) : 2 * StallTimeout(args));
  const client::SessionStats stats = session->stats();
  session.reset();
  if (ShowProgress() && !args.json) std::fprintf(stderr, "\n");
  if (!recorder.failure.empty())
    throw InputError("server " + args.server.server + ": " + recorder.failure);
  if (stats.answered + stats.late == 0 && count > 0) {
    throw InputError("server " + args.server.server + ": no frame was answered (gRPC code 14: " +
                     "the server could not be reached or kept)");
  }
  const Trajectory* gt = ground_truth.empty() ? nullptr : &ground_truth;
  PrintStreamSummary(args, recorder, stats, count, gt);
  const bool lost_frames = recorder.dropped + recorder.undelivered > 0;
  if (lost_frames && (final_state == client::LinkState::kReconnecting ||
                      final_state == client::LinkState::kConnecting)) {
    // The outputs hold what was answered; the exit status says the run did not end well.
    std::fprintf(stderr,
                 "visloc stream: server %s: the link was down at the end of the run (%llu frames "
                 "answered, %d dropped, %d undelivered)\n",
                 args.server.server.c_str(), static_cast<unsigned long long>(stats.answered),
                 recorder.dropped, recorder.undelivered);
    return 1;
  }
  return 0;
}

}  // namespace visloc::cli
