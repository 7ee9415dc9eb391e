// `visloc bench`: the engine's speed on a dataset, in one run on the same frames, with the
// baselines and a reference measured alongside so every figure can be read as a ratio that is
// stable across machines (seed paper 000, Tables 5-6):
//   - the per-step timing of the visibility-guided tracker (median and 95th percentile);
//   - the same engine with visibility prediction off (transparent world) and brute force, whole
//     frames and the map search alone (predict + project + match + pose, what prediction changes);
//   - OpenCV's ORB (ORB::create(500), default pyramid) detecting and describing each frame;
//   - global relocalization per query (features + retrieval + verification), and per step;
//   - with --cameras: a rig beside its reference camera alone, and with --rate both again at a
//     camera's pace, each frame meeting an idle engine;
//   - with --server: the round trip per frame through gRPC, one frame in flight at a time.
// Images are decoded before timing starts; only the engine's work is timed.

#include <grpcpp/grpcpp.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <iostream>
#include <memory>
#include <thread>

#include <opencv2/features2d.hpp>

#include "client/commands.h"
#include "client/connection.h"
#include "client/dataset_frames.h"
#include "client/localization_report.h"
#include "core/eval/trajectory_eval.h"
#include "core/localization/localizer.h"
#include "core/util/args.h"
#include "core/util/check.h"
#include "core/util/json.h"
#include "core/util/strings.h"
#include "core/util/timer.h"
#include "dataset/dataset.h"
#include "mapstore/map_store.h"
#include "proto/convert.h"
#include "visloc/v1/visloc.grpc.pb.h"

namespace visloc::cli {
namespace {

struct ModeRun {
  std::vector<LocalizationResult> results;
  double localized_fraction = 0.0;
  ErrorStats total_ms;
  // The part visibility prediction changes: predict + project + match + pose, per frame.
  ErrorStats map_search_ms;
  ErrorStats predicted_points;  // Map points predicted (in view), per tracked frame.
};

FrameInput InputFor(const Dataset& dataset, const std::vector<cv::Mat>& images, size_t i) {
  FrameInput input;
  input.timestamp_ns = dataset.frames[i].timestamp_ns;
  input.image = images[i];
  return input;
}

ModeRun RunMode(const std::shared_ptr<const LocalizationMap>& map, const Dataset& dataset,
                const std::vector<cv::Mat>& images, PredictionMode mode) {
  LocalizerOptions options;
  options.tracker.prediction = mode;
  Localizer localizer(map, dataset.left.camera, options);
  ModeRun run;
  std::vector<double> totals, map_search, predicted;
  int localized = 0;
  for (size_t i = 0; i < images.size(); ++i) {
    run.results.push_back(localizer.Process(InputFor(dataset, images, i)));
    const LocalizationResult& r = run.results.back();
    totals.push_back(r.stats.times.total_ms);
    const StepTimings& t = r.stats.times;
    map_search.push_back(t.predict_ms + t.project_ms + t.match_ms + t.pose_ms);
    if (r.stats.predicted > 0) predicted.push_back(r.stats.predicted);
    localized += r.has_pose && r.source != PoseSource::kMotion;
  }
  run.localized_fraction = images.empty() ? 0.0 : static_cast<double>(localized) / images.size();
  run.total_ms = ComputeErrorStats(totals);
  run.map_search_ms = ComputeErrorStats(map_search);
  run.predicted_points = ComputeErrorStats(predicted);
  return run;
}

// A rig (--cameras) beside one camera, frame by frame interleaved: three sessions on the same
// frames, the reference camera alone, the rig on one thread and the rig on `threads` threads.
struct RigRun {
  std::vector<std::string> cameras;
  int threads = 2;
  // Engine time per frame; "asleep": threaded with the helpers sleeping between frames
  // (LocalizerOptions::rig_wake_ahead off), timed in a pass of its own beside cam0 alone again.
  ErrorStats one_camera_ms, rig_ms, rig_threaded_ms;
  ErrorStats one_camera_again_ms, rig_asleep_ms;  // The asleep pass's, beside each other.
  // At a camera's pace (--rate; empty without): cam0 alone and the threaded rig in turn, each
  // frame after 1/rate s with the engine idle, per step, and the rig's helpers' wakes there.
  double rate_hz = 0.0;
  std::vector<StepSummary> one_camera_paced_steps, rig_paced_steps;
  WorkerPool::ExpectationStats paced_helper_expectations;
  // Per step of FrameTimes: where the rig's extra time goes. A rig's steps sum its cameras'
  // (CPU time); its total is the wall time, on one thread or side by side.
  std::vector<StepSummary> one_camera_steps, rig_steps, rig_threaded_steps;
  double localized_fraction = 0.0;
  std::vector<double> camera_inliers_median;  // Per camera, over the rig's fixes.
  // The threaded rig's helpers woken for a frame they expected: it came while they looked
  // (met), or not (missed); counted per helper.
  WorkerPool::ExpectationStats helper_expectations;
};

// A rig's frame as its reference camera's alone.
FrameInput ReferenceOnly(FrameInput input) {
  input.rig_images.clear();
  return input;
}

// Every frame through cam0 alone and then through the rig, each Process after `idle` with
// nothing running (zero: back to back); the two sessions' results.
struct InTurnResults {
  std::vector<LocalizationResult> one_camera, rig;
};
InTurnResults InTurn(size_t frames, const std::function<FrameInput(size_t)>& rig_input,
                     Localizer& one, Localizer& rig, std::chrono::microseconds idle) {
  InTurnResults results;
  for (size_t i = 0; i < frames; ++i) {
    const FrameInput input = rig_input(i);
    std::this_thread::sleep_for(idle);
    results.one_camera.push_back(one.Process(ReferenceOnly(input)));
    std::this_thread::sleep_for(idle);
    results.rig.push_back(rig.Process(input));
  }
  return results;
}

RigRun TimeRig(const std::shared_ptr<const LocalizationMap>& map, const Dataset& dataset,
               const std::vector<cv::Mat>& images, const std::vector<std::string>& cameras,
               int threads, double rate_hz) {
  RigRun run;
  run.cameras = cameras;
  run.threads = threads;
  run.rate_hz = rate_hz;
  const CameraRig rig = DatasetCameraRig(dataset, cameras, /*gyro=*/false);
  LocalizerOptions threaded_options;
  threaded_options.rig_threads = threads;
  Localizer one(map, dataset.left.camera, LocalizerOptions{});
  Localizer serial(map, rig, LocalizerOptions{});
  Localizer threaded(map, rig, threaded_options);
  std::vector<LocalizationResult> one_results, rig_results, threaded_results;
  std::vector<std::vector<double>> inliers(cameras.size());
  int localized = 0;
  // Frame i of the rig: the reference camera's input with the other cameras' images read.
  const auto rig_input = [&](size_t i) {
    FrameInput input = InputFor(dataset, images, i);
    for (size_t c = 1; c < cameras.size(); ++c) {
      const auto image = CameraImageAt(dataset, cameras[c], i, LocalizerOptions{}.max_rig_skew_ns);
      RigImage& rig_image = input.rig_images.emplace_back();
      if (!image) continue;
      rig_image.timestamp_ns = image->first;
      rig_image.image =
          LoadGreyImage(image->second, rig.cameras[c].width(), rig.cameras[c].height());
    }
    return input;
  };
  for (size_t i = 0; i < images.size(); ++i) {
    const FrameInput input = rig_input(i);
    one_results.push_back(one.Process(ReferenceOnly(input)));
    const LocalizationResult& r = rig_results.emplace_back(serial.Process(input));
    threaded_results.push_back(threaded.Process(input));
    if (!r.has_pose || r.source == PoseSource::kMotion) continue;
    ++localized;
    for (size_t c = 0; c < r.stats.cameras.size(); ++c) {
      inliers[c].push_back(r.stats.cameras[c].inliers);
    }
  }
  run.one_camera_steps = SummarizeSteps(one_results);
  run.rig_steps = SummarizeSteps(rig_results);
  run.one_camera_ms = run.one_camera_steps.back().ms;  // "total", the last step.
  run.rig_ms = run.rig_steps.back().ms;
  run.rig_threaded_steps = SummarizeSteps(threaded_results);
  run.rig_threaded_ms = run.rig_threaded_steps.back().ms;
  run.helper_expectations = threaded.rig_expectation_stats();
  // The threaded rig again with its helpers asleep between frames, in a pass of its own beside
  // a new one-camera session: two rigs' helpers in one pass would keep each other's core awake.
  LocalizerOptions asleep_options = threaded_options;
  asleep_options.rig_wake_ahead = false;
  Localizer one_again(map, dataset.left.camera, LocalizerOptions{});
  Localizer asleep(map, rig, asleep_options);
  const InTurnResults asleep_pass =
      InTurn(images.size(), rig_input, one_again, asleep, std::chrono::microseconds(0));
  run.one_camera_again_ms = SummarizeSteps(asleep_pass.one_camera).back().ms;
  run.rig_asleep_ms = SummarizeSteps(asleep_pass.rig).back().ms;
  if (rate_hz > 0) {
    // At the camera's pace, the way a robot's frames come to a server: each meets an engine
    // idle since the last, its caches cold, where the passes above run frames back to back.
    Localizer one_paced(map, dataset.left.camera, LocalizerOptions{});
    Localizer paced(map, rig, threaded_options);
    const auto idle = std::chrono::microseconds(static_cast<int64_t>(1e6 / rate_hz));
    const InTurnResults paced_pass = InTurn(images.size(), rig_input, one_paced, paced, idle);
    run.one_camera_paced_steps = SummarizeSteps(paced_pass.one_camera);
    run.rig_paced_steps = SummarizeSteps(paced_pass.rig);
    run.paced_helper_expectations = paced.rig_expectation_stats();
  }
  run.localized_fraction = images.empty() ? 0.0 : static_cast<double>(localized) / images.size();
  for (const auto& camera : inliers) {
    run.camera_inliers_median.push_back(ComputeErrorStats(camera).median);
  }
  return run;
}

ErrorStats TimeOrb(const std::vector<cv::Mat>& images) {
  const cv::Ptr<cv::ORB> orb = cv::ORB::create(500);
  std::vector<double> ms;
  for (const cv::Mat& image : images) {
    std::vector<cv::KeyPoint> keypoints;
    cv::Mat descriptors;
    Timer timer;
    orb->detectAndCompute(image, cv::noArray(), keypoints, descriptors);
    ms.push_back(timer.ElapsedMs());
  }
  return ComputeErrorStats(ms);
}

struct RelocalizationRun {
  ErrorStats ms;                   // Features + retrieval + verification, per query.
  std::vector<StepSummary> steps;  // The same apart (RelocalizationTimes).
  double found_fraction = 0.0;
  // Queries the tracking features did not find, which took the second pass at every scale.
  double second_pass_fraction = 0.0;
  // The same queries with the full features alone (no tracking-features pass), interleaved:
  // what a query costs without the first pass, and the second pass's share of a query that
  // needs it.
  ErrorStats full_features_ms;
  double full_features_found_fraction = 0.0;
};

// Per step of RelocalizationTimes, its median and p95 over the queries.
std::vector<StepSummary> SummarizeRelocalizationSteps(
    const std::vector<RelocalizationTimes>& times) {
  const std::pair<const char*, double RelocalizationTimes::*> fields[] = {
      {"features", &RelocalizationTimes::features_ms},
      {"retrieval", &RelocalizationTimes::retrieval_ms},
      {"matching", &RelocalizationTimes::matching_ms},
      {"ransac", &RelocalizationTimes::ransac_ms},
      {"verification", &RelocalizationTimes::verification_ms}};
  std::vector<StepSummary> steps;
  for (const auto& [name, field] : fields) {
    std::vector<double> ms;
    for (const RelocalizationTimes& t : times) ms.push_back(t.*field);
    steps.push_back({name, ComputeErrorStats(ms)});
  }
  return steps;
}

RelocalizationRun TimeRelocalization(const std::shared_ptr<const LocalizationMap>& map,
                                     const Camera& camera, const std::vector<cv::Mat>& images,
                                     int queries) {
  const QueryPipeline pipeline(map, camera, LocalizerOptions{});  // As a session and the RPC.
  LocalizerOptions full_options;
  full_options.relocalize_with_tracking_features_first = false;
  const QueryPipeline full_features(map, camera, full_options);
  std::vector<double> ms, full_ms;
  std::vector<RelocalizationTimes> times;
  int found = 0, second_passes = 0, full_found = 0;
  const size_t step = std::max<size_t>(1, images.size() / std::max(1, queries));
  for (size_t i = 0; i < images.size(); i += step) {
    Timer timer;
    const RelocalizationResult result = pipeline.RelocalizeImage(images[i]);
    ms.push_back(timer.ElapsedMs());
    found += result.success;
    second_passes += result.feature_passes == 2;
    times.push_back(result.times);
    timer.Restart();
    full_found += full_features.RelocalizeImage(images[i]).success;
    full_ms.push_back(timer.ElapsedMs());
  }
  RelocalizationRun run;
  run.ms = ComputeErrorStats(ms);
  run.steps = SummarizeRelocalizationSteps(times);
  const double n = std::max<size_t>(1, ms.size());
  run.found_fraction = found / n;
  run.second_pass_fraction = second_passes / n;
  run.full_features_ms = ComputeErrorStats(full_ms);
  run.full_features_found_fraction = full_found / n;
  return run;
}

struct GrpcRun {
  ErrorStats round_trip_ms;  // Client: from sending a frame to its answer.
  ErrorStats server_ms;      // The server's own time per frame (LocalizeResponse.timings).
  ErrorStats engine_ms;      // Of that, the engine's (timings.total_ms).
  ErrorStats in_process_ms;  // The same frames in-process, interleaved with the round trips.
  // The same bytes on a second stream, declared one column narrower than the camera: the
  // server parses and copies each frame, rejects it (STATUS_ERROR) and answers with no engine
  // work. This is the floor a frame's round trip through this server can reach on this machine.
  ErrorStats no_engine_ms;
};

// Opens a Localize stream on `map_name` with the dataset's camera and the default options.
std::unique_ptr<grpc::ClientReaderWriter<v1::LocalizeRequest, v1::LocalizeResponse>> StartSession(
    v1::Localization::Stub* stub, grpc::ClientContext* context, const Connection& server,
    const std::string& map_name, const Camera& camera) {
  server.Prepare(context);
  auto stream = stub->Localize(context);
  v1::LocalizeRequest start;
  start.mutable_start()->set_map_name(map_name);
  proto::ToProto(camera, start.mutable_start()->mutable_camera());
  stream->Write(start);
  return stream;
}

// A raw 8-bit frame request; `declared_width` < image.cols leaves the pixels as they are.
v1::LocalizeRequest RawFrameRequest(const cv::Mat& image, int64_t timestamp_ns,
                                    int declared_width) {
  v1::LocalizeRequest request;
  request.mutable_frame()->set_timestamp_ns(timestamp_ns);
  v1::RawImage* raw = request.mutable_frame()->mutable_raw();
  raw->set_width(declared_width);
  raw->set_height(image.rows);
  raw->set_stride(static_cast<uint32_t>(image.step[0]));
  raw->set_pixels(image.data, image.step[0] * image.rows);
  return request;
}

// One frame in flight: send, wait for the answer, send the next. Frames go as raw 8-bit grey
// (as a robot's camera driver delivers them), so the figure is the transport's overhead, not
// PNG decoding. An in-process session runs the same frames in alternating blocks of 50, and so
// does a stream of frames the server answers without engine work, so that the ratios compare
// runs under the same load of a shared machine (measured minutes apart, one run's median moved
// by up to 30% from the other's).
GrpcRun TimeGrpc(const Connection& server, const std::string& map_name,
                 const std::shared_ptr<const LocalizationMap>& map, const Dataset& dataset,
                 const std::vector<cv::Mat>& images) {
  const Camera& camera = dataset.left.camera;
  auto stub = v1::Localization::NewStub(server.OpenChannel());
  grpc::ClientContext tracking_context, no_engine_context;
  auto tracking = StartSession(stub.get(), &tracking_context, server, map_name, camera);
  auto no_engine = StartSession(stub.get(), &no_engine_context, server, map_name, camera);
  // The server's session options are the defaults too (an empty SessionOptions).
  Localizer in_process(map, camera, LocalizerOptions());
  std::vector<double> ms, server_ms, engine_ms, in_process_ms, no_engine_ms;
  // Sends one frame and waits for its answer; false once the stream has broken.
  const auto round_trip = [](auto* stream, const v1::LocalizeRequest& request,
                             v1::LocalizeResponse* response, std::vector<double>* round_trip_ms) {
    Timer timer;
    if (!stream->Write(request) || !stream->Read(response)) return false;
    round_trip_ms->push_back(timer.ElapsedMs());
    return true;
  };
  constexpr size_t kBlock = 50;
  bool open = true;
  bool floor_refused_all = true;  // Else the floor stream's figure is not a floor.
  for (size_t begin = 0; begin < images.size() && open; begin += kBlock) {
    const size_t end = std::min(images.size(), begin + kBlock);
    v1::LocalizeResponse response;
    for (size_t i = begin; i < end && open; ++i) {
      const int64_t stamp_ns = dataset.frames[i].timestamp_ns;
      open = round_trip(tracking.get(), RawFrameRequest(images[i], stamp_ns, images[i].cols),
                        &response, &ms);
      if (!open) break;
      server_ms.push_back(response.timings().server_ms());
      engine_ms.push_back(response.timings().total_ms());
    }
    for (size_t i = begin; i < end && open; ++i) {
      const int64_t stamp_ns = dataset.frames[i].timestamp_ns;
      open = round_trip(no_engine.get(), RawFrameRequest(images[i], stamp_ns, images[i].cols - 1),
                        &response, &no_engine_ms);
      floor_refused_all &= !open || response.status() == v1::STATUS_ERROR;
    }
    for (size_t i = begin; i < end; ++i) {
      in_process_ms.push_back(
          in_process.Process(InputFor(dataset, images, i)).stats.times.total_ms);
    }
  }
  for (auto* stream : {tracking.get(), no_engine.get()}) stream->WritesDone();
  CheckCall(tracking->Finish(), server.server);
  CheckCall(no_engine->Finish(), server.server);
  if (!floor_refused_all) {
    throw std::runtime_error(
        "bench: the server did not refuse a frame narrower than its camera, so the no-engine "
        "round trip is not a floor");
  }
  return GrpcRun{ComputeErrorStats(ms), ComputeErrorStats(server_ms), ComputeErrorStats(engine_ms),
                 ComputeErrorStats(in_process_ms), ComputeErrorStats(no_engine_ms)};
}

}  // namespace

int RunBench(const Args& raw_args) {
  std::string dataset_dir, map_path, format, server_map, cameras = "cam0";
  int frames = 0, relocalization_queries = 30, rig_threads = 2;
  double rate_hz = 0.0;
  bool json = false;
  Connection server;
  ArgParser parser("visloc bench",
                   "Times the localization engine on a dataset's frames: per-step medians and "
                   "95th percentiles, the transparent-world and brute-force baselines, OpenCV's "
                   "ORB as a machine-independent reference, global relocalization per query, and "
                   "with --server the round trip through gRPC.");
  parser.AddFlag("dataset", &dataset_dir, "dataset folder", /*required=*/true);
  parser.AddFlag("map", &map_path, "map file (.db)", /*required=*/true);
  parser.AddFlag("format", &format, "euroc or kitti (default: detected)");
  parser.AddFlag("frames", &frames, "use the first N frames (0: all)");
  parser.AddFlag("relocalization-queries", &relocalization_queries,
                 "frames spread over the sequence used as relocalization queries");
  parser.AddFlag("cameras", &cameras,
                 "also time this rig (cam0 first) beside cam0 alone, interleaved frame by frame");
  parser.AddFlag("rig-threads", &rig_threads, "with --cameras: the threaded rig's threads");
  parser.AddFlag("rate", &rate_hz,
                 "with --cameras: also time cam0 alone and the threaded rig in turn at this frame "
                 "rate, each frame after 1/RATE s idle, as frames come to a server (adds 2/RATE s "
                 "a frame; 0: not)");
  server.AddFlags(parser, /*server_required=*/false);
  parser.AddFlag("server-map", &server_map, "the map's name on the server (default: file stem)");
  parser.AddSwitch("json", &json, "print one JSON object");
  if (!parser.Parse(raw_args, std::cout)) return 0;
  server.ApplyEnvironment();
  if (frames < 0 || relocalization_queries < 1) throw UsageError("--frames >= 0, queries >= 1");
  if (rig_threads < 1) throw UsageError("--rig-threads must be at least 1");
  if (!(rate_hz >= 0 && rate_hz <= 1000)) throw UsageError("--rate must be 0..1000 frames/s");
  const std::vector<std::string> rig_cameras = ParseCameraNames(cameras);
  if (rate_hz > 0 && rig_cameras.size() < 2) {
    throw UsageError("--rate times a rig at a camera's pace: it needs --cameras with a rig");
  }
  const Dataset dataset = ReadQueryDataset(dataset_dir, format, /*odometry=*/false);
  const auto map = std::make_shared<const LocalizationMap>(mapstore::LoadMap(map_path));
  const size_t count =
      frames > 0 ? std::min<size_t>(frames, dataset.frames.size()) : dataset.frames.size();
  std::vector<cv::Mat> images;
  const Camera& camera = dataset.left.camera;
  for (size_t i = 0; i < count; ++i) {
    images.push_back(LoadGreyImage(dataset.frames[i].left_path, camera.width(), camera.height()));
  }
  if (!json) std::fprintf(stderr, "timing %zu frames of %s ...\n", count, dataset_dir.c_str());
  const ModeRun visibility = RunMode(map, dataset, images, PredictionMode::kVisibility);
  const ModeRun transparent = RunMode(map, dataset, images, PredictionMode::kTransparent);
  const ModeRun brute = RunMode(map, dataset, images, PredictionMode::kBruteForce);
  const ErrorStats orb = TimeOrb(images);
  const RelocalizationRun relocalization =
      TimeRelocalization(map, camera, images, relocalization_queries);
  std::optional<RigRun> rig;
  if (rig_cameras.size() > 1) {
    rig = TimeRig(map, dataset, images, rig_cameras, rig_threads, rate_hz);
  }
  std::optional<GrpcRun> grpc;
  if (!server.server.empty()) {
    if (server_map.empty()) server_map = std::filesystem::path(map_path).stem().string();
    grpc = TimeGrpc(server, server_map, map, dataset, images);
  }
  const std::vector<StepSummary> steps = SummarizeSteps(visibility.results);
  const double ours = visibility.total_ms.median;
  if (json) {
    JsonWriter out;
    out.BeginObject()
        .Field("frames", static_cast<int64_t>(count))
        .Field("width", static_cast<int64_t>(camera.width()))
        .Field("height", static_cast<int64_t>(camera.height()))
        .Field("map_points", static_cast<int64_t>(map->point_count()))
        .Field("map_keyframes", static_cast<int64_t>(map->keyframe_count()))
        .Field("ms_per_frame_median", ours)
        .Field("ms_per_frame_p95", visibility.total_ms.p95)
        .Field("no_visibility_ms_per_frame_median", transparent.total_ms.median)
        .Field("map_search_ms_median", visibility.map_search_ms.median)
        .Field("no_visibility_map_search_ms_median", transparent.map_search_ms.median)
        .Field("predicted_points_median", visibility.predicted_points.median)
        .Field("no_visibility_predicted_points_median", transparent.predicted_points.median)
        .Field("brute_force_ms_per_frame_median", brute.total_ms.median)
        .Field("orb_reference_ms_per_frame_median", orb.median)
        .Field("relocalization_ms_median", relocalization.ms.median)
        .Field("relocalization_found_fraction", relocalization.found_fraction)
        .Field("relocalization_second_pass_fraction", relocalization.second_pass_fraction)
        .Field("relocalization_full_features_ms_median", relocalization.full_features_ms.median)
        .Field("relocalization_full_features_found_fraction",
               relocalization.full_features_found_fraction)
        .Field("localized_fraction", visibility.localized_fraction)
        .Field("no_visibility_localized_fraction", transparent.localized_fraction)
        .Field("brute_force_localized_fraction", brute.localized_fraction);
    const auto write_steps = [&](const char* key, const std::vector<StepSummary>& summaries) {
      out.Key(key).BeginObject();
      for (const StepSummary& step : summaries) {
        out.Key(step.name)
            .BeginObject()
            .Field("median", step.ms.median)
            .Field("p95", step.ms.p95)
            .EndObject();
      }
      out.EndObject();
    };
    if (rig) {
      out.Key("rig")
          .BeginObject()
          .Field("cameras", static_cast<int64_t>(rig->cameras.size()))
          .Field("threads", static_cast<int64_t>(rig->threads))
          .Field("one_camera_ms_per_frame_median", rig->one_camera_ms.median)
          .Field("ms_per_frame_median", rig->rig_ms.median)
          .Field("threaded_ms_per_frame_median", rig->rig_threaded_ms.median)
          .Field("engine_ratio", rig->rig_ms.median / rig->one_camera_ms.median)
          .Field("threaded_latency_ratio", rig->rig_threaded_ms.median / rig->one_camera_ms.median)
          .Field("localized_fraction", rig->localized_fraction)
          .Field("asleep_ms_per_frame_median", rig->rig_asleep_ms.median)
          .Field("asleep_latency_ratio",
                 rig->rig_asleep_ms.median / rig->one_camera_again_ms.median)
          .Field("helper_expected_wakes", rig->helper_expectations.wakes)
          .Field("helper_expected_met", rig->helper_expectations.met)
          .Field("helper_expected_missed", rig->helper_expectations.missed)
          .Key("camera_inliers_median")
          .BeginArray();
      for (double inliers : rig->camera_inliers_median) out.Value(inliers);
      out.EndArray();
      write_steps("one_camera_steps", rig->one_camera_steps);
      write_steps("steps", rig->rig_steps);
      write_steps("threaded_steps", rig->rig_threaded_steps);
      if (!rig->rig_paced_steps.empty()) {
        const double one = rig->one_camera_paced_steps.back().ms.median;
        const double paced = rig->rig_paced_steps.back().ms.median;
        out.Field("paced_rate_hz", rig->rate_hz)
            .Field("paced_one_camera_ms_per_frame_median", one)
            .Field("paced_ms_per_frame_median", paced)
            .Field("paced_latency_ratio", paced / one)
            .Field("paced_helper_expected_wakes", rig->paced_helper_expectations.wakes)
            .Field("paced_helper_expected_met", rig->paced_helper_expectations.met)
            .Field("paced_helper_expected_missed", rig->paced_helper_expectations.missed);
        write_steps("one_camera_paced_steps", rig->one_camera_paced_steps);
        write_steps("paced_steps", rig->rig_paced_steps);
      }
      out.EndObject();
    }
    if (grpc) {
      out.Field("grpc_ms_per_frame_median", grpc->round_trip_ms.median)
          .Field("grpc_server_ms_per_frame_median", grpc->server_ms.median)
          .Field("grpc_server_engine_ms_per_frame_median", grpc->engine_ms.median)
          .Field("grpc_in_process_ms_per_frame_median", grpc->in_process_ms.median)
          .Field("grpc_no_engine_ms_per_frame_median", grpc->no_engine_ms.median);
    }
    write_steps("steps", steps);
    write_steps("relocalization_steps", relocalization.steps);
    out.EndObject();
    std::cout << out.str() << "\n";
    return 0;
  }
  std::printf("%zu frames %dx%d, map %zu keyframes / %zu points\n\n", count, camera.width(),
              camera.height(), map->keyframe_count(), map->point_count());
  std::printf("%-28s %10s %10s\n", "step (visibility-guided)", "median ms", "p95 ms");
  for (const StepSummary& step : steps) {
    std::printf("%-28s %10.3f %10.3f\n", step.name.c_str(), step.ms.median, step.ms.p95);
  }
  std::printf("\n%-28s %10s %10s %10s\n", "per frame", "median ms", "x ORB", "localized");
  const auto row = [&](const char* name, double ms, double localized) {
    std::printf("%-28s %10.3f %10.2f %9.1f%%\n", name, ms, ms / orb.median, 100 * localized);
  };
  row("visibility (the method)", ours, visibility.localized_fraction);
  row("transparent world", transparent.total_ms.median, transparent.localized_fraction);
  row("brute force", brute.total_ms.median, brute.localized_fraction);
  std::printf("%-28s %10.3f %10.2f\n", "ORB(500) reference", orb.median, 1.0);
  std::printf("%-28s %10.3f %10.2f            (transparent world %.3f ms, %.2fx)\n",
              "map search (predict..pose)", visibility.map_search_ms.median,
              visibility.map_search_ms.median / orb.median, transparent.map_search_ms.median,
              transparent.map_search_ms.median / visibility.map_search_ms.median);
  std::printf("%-28s %10.0f %10s            (transparent world %.0f)\n",
              "points predicted per frame", visibility.predicted_points.median, "",
              transparent.predicted_points.median);
  std::printf("%-28s %10.3f %10.2f %9.1f%%  (%.1fx one tracking frame)\n",
              "global relocalization/query", relocalization.ms.median,
              relocalization.ms.median / orb.median, 100 * relocalization.found_fraction,
              relocalization.ms.median / ours);
  for (const StepSummary& step : relocalization.steps) {
    std::printf("  %-26s %10.3f %10s            (%.2fx one tracking frame)\n", step.name.c_str(),
                step.ms.median, "", step.ms.median / ours);
  }
  std::printf("  %-26s %10.0f%%\n", "second pass (every scale)",
              100 * relocalization.second_pass_fraction);
  std::printf("%-28s %10.3f %10.2f %9.1f%%  (%.1fx one tracking frame)\n",
              "  with full features alone", relocalization.full_features_ms.median,
              relocalization.full_features_ms.median / orb.median,
              100 * relocalization.full_features_found_fraction,
              relocalization.full_features_ms.median / ours);
  if (rig) {
    std::string names, inliers;
    for (size_t c = 0; c < rig->cameras.size(); ++c) {
      names += (c ? "," : "") + rig->cameras[c];
      inliers += StrCat(c ? " / " : "", FormatFixed(rig->camera_inliers_median[c], 0));
    }
    std::printf(
        "%-28s %10.3f %10.2f %9.1f%%  (%.2fx cam0 alone's %.3f ms, interleaved; inliers %s)\n",
        ("rig " + names).c_str(), rig->rig_ms.median, rig->rig_ms.median / orb.median,
        100 * rig->localized_fraction, rig->rig_ms.median / rig->one_camera_ms.median,
        rig->one_camera_ms.median, inliers.c_str());
    const WorkerPool::ExpectationStats& woken = rig->helper_expectations;
    std::printf(
        "%-28s %10.3f %10.2f            (latency %.2fx cam0 alone's; helpers woke for %lld "
        "expected frames: %lld came in time, %lld did not)\n",
        StrCat("  on ", rig->threads, " threads").c_str(), rig->rig_threaded_ms.median,
        rig->rig_threaded_ms.median / orb.median,
        rig->rig_threaded_ms.median / rig->one_camera_ms.median,
        static_cast<long long>(woken.wakes), static_cast<long long>(woken.met),
        static_cast<long long>(woken.missed));
    std::printf(
        "%-28s %10.3f %10.2f            (latency %.2fx cam0 alone's %.3f ms, its own pass)\n",
        "  helpers asleep in between", rig->rig_asleep_ms.median,
        rig->rig_asleep_ms.median / orb.median,
        rig->rig_asleep_ms.median / rig->one_camera_again_ms.median,
        rig->one_camera_again_ms.median);
    if (!rig->rig_paced_steps.empty()) {
      const double one = rig->one_camera_paced_steps.back().ms.median;
      const double paced = rig->rig_paced_steps.back().ms.median;
      const WorkerPool::ExpectationStats& woken = rig->paced_helper_expectations;
      std::printf(
          "%-28s %10.3f %10.2f            (latency %.2fx cam0 alone's %.3f ms, in turn at %.0f "
          "frames/s; helpers woke for %lld expected frames: %lld came in time, %lld did not)\n",
          "  at the camera's pace", paced, paced / orb.median, paced / one, one, rig->rate_hz,
          static_cast<long long>(woken.wakes), static_cast<long long>(woken.met),
          static_cast<long long>(woken.missed));
      std::printf("  %-26s %10s %10s\n", "step at the pace", "cam0 ms", "rig ms");
      for (size_t s = 0; s < rig->rig_paced_steps.size(); ++s) {
        std::printf("  %-26s %10.3f %10.3f\n", rig->rig_paced_steps[s].name.c_str(),
                    rig->one_camera_paced_steps[s].ms.median, rig->rig_paced_steps[s].ms.median);
      }
    }
  }
  if (grpc) {
    const double round_trip = grpc->round_trip_ms.median;
    const double in_process = grpc->in_process_ms.median;
    std::printf(
        "%-28s %10.3f %10.2f            (%.2fx the interleaved in-process %.3f ms; the "
        "server's own %.3f ms, its engine %.3f ms)\n",
        "through gRPC (round trip)", round_trip, round_trip / orb.median, round_trip / in_process,
        in_process, grpc->server_ms.median, grpc->engine_ms.median);
    std::printf(
        "%-28s %10.3f %10.2f            (the same bytes answered without engine work: "
        "%.2fx the in-process frame)\n",
        "gRPC floor (no engine)", grpc->no_engine_ms.median, grpc->no_engine_ms.median / orb.median,
        grpc->no_engine_ms.median / in_process);
  }
  return 0;
}

}  // namespace visloc::cli
