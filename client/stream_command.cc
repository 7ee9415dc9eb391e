// `visloc stream`: a robot's side of a localization session. Reads a dataset and streams its
// left images (as the files' PNG/JPEG bytes, with odometry and gyro when asked) to
// visloc-server, at the dataset's rate or as fast as possible, and writes/prints the same
// outputs as `visloc localize`, plus the end-to-end latency seen by the client.

#include <grpcpp/grpcpp.h>

#include <chrono>
#include <cstdio>
#include <iostream>
#include <mutex>
#include <thread>

#include "client/commands.h"
#include "client/connection.h"
#include "client/dataset_frames.h"
#include "client/localization_report.h"
#include "core/eval/trajectory_eval.h"
#include "core/util/args.h"
#include "core/util/check.h"
#include "core/util/json.h"
#include "core/util/strings.h"
#include "core/util/text_file.h"
#include "dataset/dataset.h"
#include "dataset/tum.h"
#include "proto/convert.h"
#include "visloc/v1/visloc.grpc.pb.h"

namespace visloc::cli {
namespace {

namespace v1 = ::visloc::v1;
using Clock = std::chrono::steady_clock;

struct StreamArgs {
  Connection server;
  std::string map_name, dataset_dir, format, trajectory_path, stats_path, gt_path;
  double rate_hz = -1.0;  // Negative: the dataset's timestamps; 0: as fast as possible.
  std::string policy = "all";
  bool odometry = false, json = false;
  int frames = 0;
};

v1::LocalizeRequest StartRequest(const StreamArgs& args, const Dataset& dataset) {
  v1::LocalizeRequest request;
  v1::SessionStart* start = request.mutable_start();
  start->set_map_name(args.map_name);
  start->set_robot_id("visloc-stream");
  proto::ToProto(dataset.left.camera, start->mutable_camera());
  start->mutable_options()->set_drop_policy(args.policy == "newest" ? v1::NEWEST_ONLY
                                                                    : v1::PROCESS_ALL);
  if (args.odometry)
    proto::ToProto(dataset.left.body_from_cam, start->mutable_options()->mutable_body_from_cam());
  return request;
}

v1::LocalizeRequest FrameRequest(const StreamArgs& args, const Dataset& dataset, size_t index) {
  const FrameInput input = DatasetFrameInput(dataset, index, args.odometry, args.odometry);
  v1::LocalizeRequest request;
  proto::ToProto(input, ReadFileBytes(dataset.frames[index].left_path), request.mutable_frame());
  return request;
}

}  // namespace

int RunStream(const Args& raw_args) {
  StreamArgs args;
  ArgParser parser("visloc stream",
                   "Streams a dataset's left images to visloc-server as one robot session and "
                   "reports every frame's answer: the TUM trajectory, the per-frame statistics "
                   "CSV, a live line on a terminal, and a summary with the client-side latency.");
  args.server.AddFlags(parser);
  parser.AddFlag("map", &args.map_name, "map name on the server", true);
  parser.AddFlag("dataset", &args.dataset_dir, "dataset folder (EuRoC or KITTI layout)", true);
  parser.AddFlag("format", &args.format, "euroc or kitti (default: detected)");
  parser.AddFlag(
      "rate", &args.rate_hz,
      "frames per second to send (default: the dataset's timing; 0: as fast as possible)");
  parser.AddFlag("policy", &args.policy, "all (answer every frame) or newest (drop stale frames)");
  parser.AddSwitch("odometry", &args.odometry, "send the dataset's odometry and gyro");
  parser.AddFlag("trajectory", &args.trajectory_path, "write the estimated poses (TUM)");
  parser.AddFlag("stats", &args.stats_path, "write per-frame statistics (CSV)");
  parser.AddFlag("gt", &args.gt_path, "ground truth (TUM, map frame) for the summary");
  parser.AddFlag("frames", &args.frames, "stop after this many frames (0: all)");
  parser.AddSwitch("json", &args.json, "print the summary as one JSON object");
  if (!parser.Parse(raw_args, std::cout)) return 0;
  args.server.ApplyEnvironment();
  if (args.rate_hz > 1000)
    throw UsageError("--rate must be at most 1000 Hz (0: as fast as possible)");
  if (args.policy != "all" && args.policy != "newest")
    throw UsageError("--policy is all or newest");
  const Dataset dataset = ReadQueryDataset(args.dataset_dir, args.format, args.odometry);
  const Trajectory ground_truth = args.gt_path.empty() ? Trajectory{} : ReadTum(args.gt_path);
  const size_t count = args.frames > 0 ? std::min<size_t>(args.frames, dataset.frames.size())
                                       : dataset.frames.size();

  auto stub = v1::Localization::NewStub(args.server.OpenChannel());
  grpc::ClientContext context;
  args.server.Prepare(&context);
  auto stream = stub->Localize(&context);
  std::vector<Clock::time_point> sent(count);
  std::mutex sent_mutex;
  std::thread writer([&] {
    bool ok = stream->Write(StartRequest(args, dataset));
    const Clock::time_point start = Clock::now();
    const int64_t t0 = dataset.frames.front().timestamp_ns;
    for (size_t i = 0; i < count && ok; ++i) {
      if (args.rate_hz < 0) {
        std::this_thread::sleep_until(
            start + std::chrono::nanoseconds(dataset.frames[i].timestamp_ns - t0));
      } else if (args.rate_hz > 0) {
        std::this_thread::sleep_until(
            start + std::chrono::nanoseconds(static_cast<int64_t>(i * 1e9 / args.rate_hz)));
      }
      v1::LocalizeRequest request;
      try {
        request = FrameRequest(args, dataset, i);
      } catch (const InputError& e) {
        std::fprintf(stderr, "visloc stream: frame %zu: %s (sent without an image)\n", i, e.what());
        request.mutable_frame()->set_timestamp_ns(dataset.frames[i].timestamp_ns);
      }
      {
        std::lock_guard<std::mutex> lock(sent_mutex);
        sent[i] = Clock::now();
      }
      ok = stream->Write(request);
    }
    stream->WritesDone();
  });

  RunReport report;
  std::vector<double> latency_ms;
  int errors = 0, skipped = 0;
  std::string skipped_reason;
  v1::LocalizeResponse response;
  while (stream->Read(&response)) {
    const size_t index = response.frame_index();
    if (index < count) {
      std::lock_guard<std::mutex> lock(sent_mutex);
      latency_ms.push_back(
          std::chrono::duration<double, std::milli>(Clock::now() - sent[index]).count());
    }
    if (response.status() == v1::STATUS_ERROR) {
      ++errors;
      std::fprintf(stderr, "visloc stream: frame %zu: server: %s\n", index,
                   response.error().c_str());
      continue;
    }
    if (response.status() == v1::STATUS_SKIPPED) {
      // A reason means the server refused the frame (its rate limit), not the drop policy the
      // client chose: say so once.
      if (!response.error().empty() && skipped_reason.empty()) {
        skipped_reason = response.error();
        std::fprintf(stderr, "visloc stream: frame %zu skipped by the server: %s\n", index,
                     skipped_reason.c_str());
      }
      ++skipped;
      continue;
    }
    report.Add(proto::FromProto(response));
    if (ShowProgress() && !args.json) {
      std::fprintf(stderr, "\r%-60s latency %6.1f ms", report.ProgressLine(count).c_str(),
                   latency_ms.empty() ? 0.0 : latency_ms.back());
    }
  }
  writer.join();
  const grpc::Status status = stream->Finish();
  if (ShowProgress() && !args.json) std::fprintf(stderr, "\n");
  CheckCall(status, args.server.server);
  if (!args.trajectory_path.empty()) WriteTum(args.trajectory_path, report.PosedTrajectory());
  if (!args.stats_path.empty()) report.WriteStatsCsv(args.stats_path);
  const ErrorStats latency = ComputeErrorStats(latency_ms);
  std::vector<double> sorted = latency_ms;
  std::sort(sorted.begin(), sorted.end());
  const double p99 =
      sorted.empty() ? 0.0 : sorted[std::min(sorted.size() - 1, sorted.size() * 99 / 100)];
  const Trajectory* gt = ground_truth.empty() ? nullptr : &ground_truth;
  if (args.json) {
    JsonWriter json;
    json.BeginObject().Field("server", args.server.server).Field("map", args.map_name);
    json.Field("errors", static_cast<int64_t>(errors))
        .Field("skipped", static_cast<int64_t>(skipped));
    json.Field("latency_ms_mean", latency.mean)
        .Field("latency_ms_p50", latency.median)
        .Field("latency_ms_p99", p99);
    report.WriteSummaryJson(json, gt);
    json.EndObject();
    std::cout << json.str() << "\n";
  } else {
    std::printf("server %s, map %s: %zu frames sent, %d errors, %d skipped\n",
                args.server.server.c_str(), args.map_name.c_str(), count, errors, skipped);
    report.PrintSummary(stdout, gt);
    std::printf("latency (client, send to answer): mean %.2f ms, p50 %.2f ms, p99 %.2f ms\n",
                latency.mean, latency.median, p99);
  }
  return 0;
}

}  // namespace visloc::cli
