// `visloc load`: many robots against one visloc-server, from one process that costs little, to
// find how many real-resolution robots a server holds. Every left image of a dataset is encoded
// once (JPEG, as the client library sends it), then N sessions of the client library stream
// those bytes at a robot's rate, each on its own thread and staggered over one frame period (as
// robots started at random would be). The dataset is played forwards then backwards, so each
// robot moves continuously however long the run. Each frame's latency (submit to answer) and
// fate (answered, skipped by the server, dropped by the link's policy, late) is recorded; the
// summary gives the latency percentiles over every answer and per robot, and the client's own
// CPU time, which says how much of the machine the generator took from the server.

#include <sys/resource.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <mutex>
#include <thread>
#include <vector>

#include "client/commands.h"
#include "client/connection.h"
#include "client/dataset_frames.h"
#include "client/localization_report.h"
#include "core/util/args.h"
#include "core/util/check.h"
#include "core/util/json.h"
#include "core/util/strings.h"
#include "dataset/dataset.h"
#include "proto/convert.h"
#include "visloc/client/session.h"

namespace visloc::cli {
namespace {

namespace v1 = ::visloc::v1;
using Clock = std::chrono::steady_clock;

struct LoadArgs {
  Connection server;
  std::string map_name, dataset_dir, format;
  int robots = 8;
  double rate_hz = 20.0;
  double duration_s = 10.0;
  int jpeg_quality = 90;
  std::string policy = "newest";
  double max_p99_ms = 50.0;  // The capacity criterion the summary checks.
  double arrive_every_s = 0.0;  // Robot r opens its session r times this after the first.
  bool json = false;
};

// What happened to one robot's frames.
struct RobotRecord {
  std::vector<double> latency_ms;  // Answered in time.
  std::vector<double> answered_s;  // When each of those came, from the run's start.
  std::vector<double> engine_ms;   // Their time inside the engine (the server's timings).
  std::vector<double> server_ms;   // From the server's receipt to its reply: decoding, waiting
                                   // for a worker and the engine.
  int answered = 0, localized = 0, skipped = 0, late = 0, dropped = 0, undelivered = 0;
  std::string failure;  // The server refused the session.
  // The server refused the session for capacity (RESOURCE_EXHAUSTED) this many times; a robot
  // refused and never answered was not admitted, and its frames are not the server's latency.
  int capacity_refusals = 0;
  // Frames dropped while the robot waited to be admitted (refused, backing off): not the
  // latency of a robot the server serves.
  int awaiting_admission = 0;
  bool refused() const { return capacity_refusals > 0 && answered == 0; }
};

// Frame k of a forwards-then-backwards play of `count` frames.
size_t PingPong(size_t k, size_t count) {
  if (count < 2) return 0;
  const size_t period = 2 * (count - 1), phase = k % period;
  return phase < count ? phase : period - phase;
}

// The latencies answered in each of `periods` spans of `span_s` from the run's start (answers
// after the last span count in it).
std::vector<std::vector<double>> ByPeriod(const std::vector<double>& latency_ms,
                                          const std::vector<double>& answered_s, double span_s,
                                          int periods) {
  std::vector<std::vector<double>> by_period(periods);
  for (size_t k = 0; k < latency_ms.size(); ++k) {
    const int period = std::clamp(static_cast<int>(answered_s[k] / span_s), 0, periods - 1);
    by_period[period].push_back(latency_ms[k]);
  }
  return by_period;
}

double CpuSeconds() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_utime.tv_sec + usage.ru_stime.tv_sec +
         1e-6 * (usage.ru_utime.tv_usec + usage.ru_stime.tv_usec);
}

// The server's reason when admission control refuses a session (server/admission.h).
bool IsCapacityRefusal(const std::string& detail) {
  return detail.find("server at capacity") != std::string::npos;
}

void Record(const client::Event& e, double since_start_s, RobotRecord* robot) {
  switch (e.kind) {
    case client::Event::Kind::kResult:
      if (e.response.status() == v1::STATUS_SKIPPED) {
        ++robot->skipped;
        break;
      }
      if (e.response.status() == v1::STATUS_ERROR) {
        if (robot->failure.empty()) robot->failure = e.response.error();
        break;
      }
      ++robot->answered;
      robot->localized += e.response.has_map_from_cam();
      robot->latency_ms.push_back(e.latency_ms);
      robot->answered_s.push_back(since_start_s);
      robot->engine_ms.push_back(e.response.timings().total_ms());
      robot->server_ms.push_back(e.response.timings().server_ms());
      break;
    case client::Event::Kind::kLate:
      ++robot->late;
      break;
    case client::Event::Kind::kDropped:
      ++(robot->refused() ? robot->awaiting_admission : robot->dropped);
      break;
    case client::Event::Kind::kUndelivered:
      // Sent before the server's capacity refusal came back: the robot was not admitted.
      ++(IsCapacityRefusal(e.detail) && robot->answered == 0 ? robot->awaiting_admission
                                                             : robot->undelivered);
      break;
    case client::Event::Kind::kLinkState:
      if (e.link_state == client::LinkState::kFailed && robot->failure.empty()) {
        robot->failure = e.detail;
      }
      robot->capacity_refusals += IsCapacityRefusal(e.detail);
      break;
  }
}

client::SessionOptions RobotOptions(const LoadArgs& args, const Dataset& dataset, int robot) {
  client::SessionOptions o;
  args.server.ToLibrary(&o);
  o.map_name = args.map_name;
  o.robot_id = StrCat("load-", robot);
  proto::ToProto(dataset.left.camera, &o.camera);
  o.session.set_drop_policy(args.policy == "all" ? v1::PROCESS_ALL : v1::NEWEST_ONLY);
  o.give_up_after = std::chrono::seconds(10);
  return o;
}

// One robot: its session opened at `start`, then frames at the rate until `end`.
void DriveRobot(const client::SessionOptions& options, std::unique_ptr<client::Session>* opened,
                const std::vector<std::string>& encoded, const Dataset& dataset, double rate_hz,
                Clock::time_point start, Clock::time_point end) {
  std::this_thread::sleep_until(start);
  *opened = client::Session::Open(options);
  client::Session* session = opened->get();
  const auto period = std::chrono::nanoseconds(static_cast<int64_t>(1e9 / rate_hz));
  for (size_t k = 0;; ++k) {
    const Clock::time_point due = start + k * period;
    if (due >= end || session->link_state() == client::LinkState::kFailed) return;
    std::this_thread::sleep_until(due);
    client::Frame frame;
    // Timestamps move on with the robot's clock while the images play back and forth.
    frame.timestamp_ns = dataset.frames.front().timestamp_ns + static_cast<int64_t>(k) *
                                                                   period.count();
    frame.encoded = encoded[PingPong(k, encoded.size())];
    session->Submit(frame);
  }
}

void ParseLoadArgs(const Args& raw_args, LoadArgs* args, bool* run) {
  ArgParser parser("visloc load",
                   "Finds how many robots a visloc-server answers in time: N robots at a "
                   "robot's rate stream a dataset's left images (encoded once, as JPEG) from "
                   "this one process, and the latency of every answer is reported, with frames "
                   "skipped by the server or dropped by the link's policy.");
  args->server.AddFlags(parser);
  parser.AddFlag("map", &args->map_name, "map name on the server", true);
  parser.AddFlag("dataset", &args->dataset_dir, "dataset folder (EuRoC or KITTI layout)", true);
  parser.AddFlag("format", &args->format, "euroc or kitti (default: detected)");
  parser.AddFlag("robots", &args->robots, "robots streaming at once");
  parser.AddFlag("rate", &args->rate_hz, "frames per second each robot sends");
  parser.AddFlag("duration-s", &args->duration_s, "how long the robots stream");
  parser.AddFlag("jpeg-quality", &args->jpeg_quality, "1..100, the frames' JPEG quality");
  parser.AddFlag("policy", &args->policy,
                 "newest (a live robot: the server drops stale frames) or all");
  parser.AddFlag("arrive-every-s", &args->arrive_every_s,
                 "robots join one after another this far apart (each streams until the end); "
                 "0: all at once");
  parser.AddFlag("max-p99-ms", &args->max_p99_ms,
                 "the latency the summary holds the server to: p99 over every answer");
  parser.AddSwitch("json", &args->json, "print the summary as one JSON object");
  *run = parser.Parse(raw_args, std::cout);
  if (!*run) return;
  args->server.ApplyEnvironment();
  if (args->robots < 1 || args->robots > 256) throw UsageError("--robots is 1..256");
  if (!(args->rate_hz > 0 && args->rate_hz <= 1000)) throw UsageError("--rate is (0, 1000] Hz");
  if (!(args->duration_s > 0 && args->duration_s <= 3600)) {
    throw UsageError("--duration-s is (0, 3600] s");
  }
  if (!(args->arrive_every_s >= 0 &&
        args->arrive_every_s * (args->robots - 1) < args->duration_s)) {
    throw UsageError("--arrive-every-s must let the last robot arrive within --duration-s");
  }
  if (args->jpeg_quality < 1 || args->jpeg_quality > 100) {
    throw UsageError("--jpeg-quality is 1..100");
  }
  if (args->policy != "newest" && args->policy != "all") {
    throw UsageError("--policy is newest or all");
  }
}

}  // namespace

int RunLoad(const Args& raw_args) {
  LoadArgs args;
  bool run = false;
  ParseLoadArgs(raw_args, &args, &run);
  if (!run) return 0;
  const Dataset dataset = ReadQueryDataset(args.dataset_dir, args.format, false);
  if (dataset.frames.empty()) throw InputError(args.dataset_dir + ": no frames");
  std::vector<std::string> encoded;
  for (const FrameRecord& f : dataset.frames) {
    encoded.push_back(client::EncodeImage(
        LoadGreyImage(f.left_path, dataset.left.camera.width(), dataset.left.camera.height()),
        client::Encoding::kJpeg, args.jpeg_quality));
  }
  double encoded_bytes = 0;
  for (const std::string& e : encoded) encoded_bytes += static_cast<double>(e.size());

  std::vector<RobotRecord> records(args.robots);
  std::mutex records_mutex;
  std::vector<client::SessionOptions> options(args.robots);
  const Clock::time_point start = Clock::now() + std::chrono::milliseconds(200);
  for (int r = 0; r < args.robots; ++r) {
    options[r] = RobotOptions(args, dataset, r);
    options[r].on_event = [&records, &records_mutex, r, start](const client::Event& e) {
      const double since_start_s = std::chrono::duration<double>(Clock::now() - start).count();
      const std::lock_guard<std::mutex> lock(records_mutex);
      Record(e, since_start_s, &records[r]);
    };
  }
  std::vector<std::unique_ptr<client::Session>> sessions(args.robots);
  const double cpu_before_s = CpuSeconds();
  const Clock::time_point end =
      start + std::chrono::nanoseconds(static_cast<int64_t>(args.duration_s * 1e9));
  std::vector<std::thread> drivers;
  for (int r = 0; r < args.robots; ++r) {
    // Staggered over one period, as robots started at random would be; arriving one after
    // another with --arrive-every-s.
    const auto offset =
        std::chrono::nanoseconds(static_cast<int64_t>(1e9 / args.rate_hz * r / args.robots)) +
        std::chrono::nanoseconds(static_cast<int64_t>(1e9 * args.arrive_every_s * r));
    drivers.emplace_back(DriveRobot, std::cref(options[r]), &sessions[r], std::cref(encoded),
                         std::cref(dataset), args.rate_hz, start + offset, end);
  }
  for (std::thread& d : drivers) d.join();
  for (auto& s : sessions) {
    if (s) s->Close(std::chrono::milliseconds(2000));
  }
  const double streamed_s = std::chrono::duration<double>(Clock::now() - start).count();
  const double cpu_s = CpuSeconds() - cpu_before_s;
  std::vector<int> submitted_by(args.robots);
  for (int r = 0; r < args.robots; ++r) {
    submitted_by[r] = sessions[r] ? static_cast<int>(sessions[r]->stats().submitted) : 0;
  }
  sessions.clear();

  const std::lock_guard<std::mutex> lock(records_mutex);
  std::vector<double> all_ms, robot_p99_ms, engine_ms, server_ms;
  std::vector<double> all_answered_s;  // When each of all_ms came.
  int answered = 0, localized = 0, skipped = 0, late = 0, dropped = 0, undelivered = 0;
  int submitted = 0, refused_robots = 0, awaiting_admission = 0;
  for (int i = 0; i < args.robots; ++i) {
    const RobotRecord& r = records[i];
    if (!r.failure.empty()) throw InputError("server " + args.server.server + ": " + r.failure);
    if (r.refused()) {
      ++refused_robots;
      continue;
    }
    submitted += submitted_by[i] - r.awaiting_admission;
    awaiting_admission += r.awaiting_admission;
    all_ms.insert(all_ms.end(), r.latency_ms.begin(), r.latency_ms.end());
    all_answered_s.insert(all_answered_s.end(), r.answered_s.begin(), r.answered_s.end());
    engine_ms.insert(engine_ms.end(), r.engine_ms.begin(), r.engine_ms.end());
    server_ms.insert(server_ms.end(), r.server_ms.begin(), r.server_ms.end());
    robot_p99_ms.push_back(LatencyPercentile(r.latency_ms, 0.99));
    answered += r.answered;
    localized += r.localized;
    skipped += r.skipped;
    late += r.late;
    dropped += r.dropped;
    undelivered += r.undelivered;
  }
  const int frames = submitted;
  // A load at steady state has the same p99 in the last third of its run as in the second; a
  // soak reads its minutes.
  const auto thirds_ms = ByPeriod(all_ms, all_answered_s, args.duration_s / 3, 3);
  const int minutes = std::max(1, static_cast<int>(std::ceil(args.duration_s / 60.0)));
  const auto minutes_ms = ByPeriod(all_ms, all_answered_s, 60.0, minutes);
  const double p50 = LatencyPercentile(all_ms, 0.5), p95 = LatencyPercentile(all_ms, 0.95),
               p99 = LatencyPercentile(all_ms, 0.99);
  const double worst_robot_p99 =
      robot_p99_ms.empty() ? 0.0 : *std::max_element(robot_p99_ms.begin(), robot_p99_ms.end());
  const int not_answered = skipped + late + dropped + undelivered;
  const bool held = p99 <= args.max_p99_ms && not_answered <= 0.01 * frames;
  if (args.json) {
    JsonWriter json;
    json.BeginObject()
        .Field("robots", static_cast<int64_t>(args.robots))
        .Field("rate_hz", args.rate_hz)
        .Field("duration_s", args.duration_s)
        .Field("refused_robots", static_cast<int64_t>(refused_robots))
        .Field("frames_awaiting_admission", static_cast<int64_t>(awaiting_admission))
        .Field("frames", static_cast<int64_t>(frames))
        .Field("answered", static_cast<int64_t>(answered))
        .Field("localized", static_cast<int64_t>(localized))
        .Field("skipped", static_cast<int64_t>(skipped))
        .Field("late", static_cast<int64_t>(late))
        .Field("dropped", static_cast<int64_t>(dropped))
        .Field("undelivered", static_cast<int64_t>(undelivered))
        .Field("answers_per_s", answered / streamed_s)
        .Field("latency_ms_p50", p50)
        .Field("latency_ms_p95", p95)
        .Field("latency_ms_p99", p99)
        .Field("worst_robot_p99_ms", worst_robot_p99)
        .Field("latency_ms_p99_first_third", LatencyPercentile(thirds_ms[0], 0.99))
        .Field("latency_ms_p99_second_third", LatencyPercentile(thirds_ms[1], 0.99))
        .Field("latency_ms_p99_last_third", LatencyPercentile(thirds_ms[2], 0.99))
        .Field("engine_ms_p50", LatencyPercentile(engine_ms, 0.5))
        .Field("server_ms_p50", LatencyPercentile(server_ms, 0.5))
        .Field("jpeg_bytes_mean", encoded_bytes / encoded.size())
        .Field("client_cpu_fraction", cpu_s / streamed_s)
        .Field("held", held)
        .Key("minutes")
        .BeginArray();
    for (int m = 0; m < minutes; ++m) {
      json.BeginObject()
          .Field("minute", static_cast<int64_t>(m + 1))
          .Field("answers", static_cast<int64_t>(minutes_ms[m].size()))
          // Named apart from the run's own figures, which scripts read by first occurrence.
          .Field("p50_ms", LatencyPercentile(minutes_ms[m], 0.5))
          .Field("p95_ms", LatencyPercentile(minutes_ms[m], 0.95))
          .Field("p99_ms", LatencyPercentile(minutes_ms[m], 0.99))
          .EndObject();
    }
    json.EndArray().EndObject();
    std::cout << json.str() << "\n";
  } else {
    std::printf("%d robots at %.0f Hz for %.1f s (%dx%d JPEG q%d, %.0f KiB a frame), map %s\n",
                args.robots, args.rate_hz, args.duration_s, dataset.left.camera.width(),
                dataset.left.camera.height(), args.jpeg_quality,
                encoded_bytes / encoded.size() / 1024.0, args.map_name.c_str());
    if (refused_robots > 0 || awaiting_admission > 0) {
      std::printf(
          "%d of %d robots refused: the server was at capacity (their frames are left "
          "out, and the %d frames of admitted robots sent while they waited)\n",
          refused_robots, args.robots, awaiting_admission);
    }
    std::printf("answered %d of %d frames (%d localized), %.1f answers/s; skipped %d, late %d, "
                "dropped %d, undelivered %d\n",
                answered, frames, localized, answered / streamed_s, skipped, late, dropped,
                undelivered);
    std::printf("latency (submit to answer): p50 %.1f ms, p95 %.1f ms, p99 %.1f ms; worst robot's "
                "p99 %.1f ms\n",
                p50, p95, p99, worst_robot_p99);
    std::printf("p99 by thirds of the run: %.1f, %.1f, %.1f ms\n",
                LatencyPercentile(thirds_ms[0], 0.99), LatencyPercentile(thirds_ms[1], 0.99),
                LatencyPercentile(thirds_ms[2], 0.99));
    std::printf("in the server (p50): %.2f ms from receipt to reply, %.2f ms of it in the engine\n",
                LatencyPercentile(server_ms, 0.5), LatencyPercentile(engine_ms, 0.5));
    std::printf("this generator used %.0f%% of one core\n", 100.0 * cpu_s / streamed_s);
    std::printf("%s: p99 %s %.0f ms and %d of %d frames not answered in time\n",
                held ? "held" : "not held", p99 <= args.max_p99_ms ? "<=" : ">", args.max_p99_ms,
                not_answered, frames);
  }
  return 0;
}

}  // namespace visloc::cli
