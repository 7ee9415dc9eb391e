// `visloc localize`: the localization engine in-process on a dataset, frame by frame, exactly as
// a server session would run it (batch runs, debugging, and the reference for the server's
// overhead).

#include <cstdio>
#include <iostream>
#include <memory>

#include "client/commands.h"
#include "client/dataset_frames.h"
#include "client/localization_report.h"
#include "core/localization/localizer.h"
#include "core/util/args.h"
#include "core/util/check.h"
#include "core/util/json.h"
#include "core/util/strings.h"
#include "dataset/dataset.h"
#include "dataset/frame_range.h"
#include "dataset/tum.h"
#include "mapstore/map_store.h"

namespace visloc::cli {
namespace {

struct LocalizeArgs {
  std::string map_path, dataset_dir, format, trajectory_path, stats_path, gt_path, frames;
  std::string mode = "visibility";
  std::string blackout;  // "START,DURATION" in seconds from the first frame.
  std::string cameras = "cam0";
  std::string frame = "map";  // Of the trajectory: map or site.
  bool odometry = false, no_gyro = false, planar = false, bridge_constant_velocity = false;
  bool json = false, all_scales = false;
  int k = 10;
  int rig_threads = 1;
  int max_features = LocalizerOptions{}.max_query_features;
  double threshold = 0.2;
};

// The [start, end) window in seconds, or none.
std::optional<std::pair<double, double>> ParseBlackout(const std::string& text) {
  if (text.empty()) return std::nullopt;
  const std::vector<std::string> parts = Split(text, ',');
  if (parts.size() != 2) throw UsageError("--blackout wants START,DURATION in seconds");
  const std::optional<double> start = ParseDouble(parts[0]);
  const std::optional<double> duration = ParseDouble(parts[1]);
  if (!start || !duration || *start < 0 || *duration <= 0) {
    throw UsageError("--blackout wants START >= 0 and DURATION > 0 in seconds, got '" + text + "'");
  }
  return std::make_pair(*start, *start + *duration);
}

FrameInput MakeFrameInput(const Dataset& dataset, size_t index, const LocalizeArgs& args,
                          const std::vector<std::string>& cameras, const CameraRig& rig,
                          int64_t max_rig_skew_ns,
                          const std::optional<std::pair<double, double>>& blackout) {
  FrameInput input =
      DatasetFrameInput(dataset, index, args.odometry, args.odometry && !args.no_gyro);
  const Camera& camera = dataset.left.camera;
  input.image = LoadGreyImage(dataset.frames[index].left_path, camera.width(), camera.height());
  const double t_s = NsToSeconds(input.timestamp_ns - dataset.frames.front().timestamp_ns);
  // The front pair is covered; the robot keeps walking, and its other cameras see.
  const bool covered = blackout && t_s >= blackout->first && t_s < blackout->second;
  if (covered) input.image.setTo(0);
  for (size_t c = 1; c < cameras.size(); ++c) {
    RigImage& rig_image = input.rig_images.emplace_back();
    const auto image = CameraImageAt(dataset, cameras[c], index, max_rig_skew_ns);
    if (!image) continue;  // That camera gave no image for this frame.
    rig_image.timestamp_ns = image->first;
    rig_image.image = LoadGreyImage(image->second, rig.cameras[c].width(), rig.cameras[c].height());
    if (covered && cameras[c] == "cam1") rig_image.image.setTo(0);
  }
  return input;
}

}  // namespace

int RunLocalize(const Args& raw_args) {
  LocalizeArgs args;
  ArgParser parser(
      "visloc localize",
      "Localizes every left image of a dataset in a map, in-process (the engine a server session "
      "runs): visibility-guided tracking, relocalization, and with --odometry the fusion of the "
      "dataset's odometry and gyro. Writes the TUM trajectory (posed frames only) and the "
      "per-frame statistics CSV, and prints a summary.");
  parser.AddFlag("map", &args.map_path, "map file (.db)", /*required=*/true);
  parser.AddFlag("dataset", &args.dataset_dir, "dataset folder (EuRoC or KITTI layout)", true);
  parser.AddFlag("format", &args.format, "euroc or kitti (default: detected)");
  parser.AddFlag("trajectory", &args.trajectory_path, "write the estimated poses (TUM)");
  parser.AddFlag("frame", &args.frame,
                 "the trajectory's frame: map (the first camera's) or site (z up: the frame map "
                 "align tied the map to, else its level frame; a map that knows up)");
  parser.AddFlag("stats", &args.stats_path, "write per-frame statistics (CSV)");
  parser.AddSwitch("odometry", &args.odometry, "fuse the dataset's odometry (and gyro)");
  parser.AddSwitch("no-gyro", &args.no_gyro, "with --odometry: leave the gyro out");
  parser.AddSwitch("planar", &args.planar,
                   "planar motion: the camera stays at the height of the map's keyframes");
  parser.AddFlag("mode", &args.mode, "visibility, transparent or brute_force (baselines)");
  parser.AddFlag("k", &args.k, "visibility: nearest keyframes K");
  parser.AddFlag("threshold", &args.threshold, "visibility: probability threshold P_t");
  parser.AddFlag("max-features", &args.max_features,
                 "keypoints per image (0: the map's own count)");
  parser.AddSwitch("all-scales", &args.all_scales,
                   "detect at all of the map's scales (default: the finest only, faster)");
  parser.AddFlag("blackout", &args.blackout,
                 "START,DURATION: black images in this window (s from the first frame; cam0 and "
                 "cam1, the front pair)");
  parser.AddFlag("rig-threads", &args.rig_threads,
                 "with --cameras: threads a frame's cameras are worked on side by side");
  parser.AddFlag("cameras", &args.cameras,
                 "the rig localized with: cam0 (the reference, reported) then others, e.g. "
                 "cam0,cam1 (the stereo pair) or cam0,cam2 (EuRoC's cam2 folder)");
  parser.AddSwitch("bridge-constant-velocity", &args.bridge_constant_velocity,
                   "bridge frames without a fix by constant velocity (for comparison only)");
  parser.AddFlag("frames", &args.frames,
                 "localize only these frames: N (the first N), BEGIN:END or BEGIN:END:STEP");
  parser.AddFlag("gt", &args.gt_path, "ground truth (TUM, map frame) for the summary");
  parser.AddSwitch("json", &args.json, "print the summary as one JSON object");
  if (!parser.Parse(raw_args, std::cout)) return 0;
  const auto blackout = ParseBlackout(args.blackout);

  const Dataset dataset = SelectFrames(
      ReadQueryDataset(args.dataset_dir, args.format, args.odometry), ParseFrameRange(args.frames));
  const Trajectory ground_truth = args.gt_path.empty() ? Trajectory{} : ReadTum(args.gt_path);
  auto map = std::make_shared<const LocalizationMap>(mapstore::LoadMap(args.map_path));

  LocalizerOptions options;
  options.tracker.prediction = ParsePredictionMode(args.mode);
  options.tracker.visibility.k = args.k;
  options.tracker.visibility.probability_threshold = args.threshold;
  options.motion.bridge_with_constant_velocity = args.bridge_constant_velocity;
  options.max_query_features = args.max_features;
  options.finest_scale_only = !args.all_scales;
  if (args.rig_threads < 1) throw UsageError("--rig-threads must be at least 1");
  options.rig_threads = args.rig_threads;
  if (args.planar) options.motion.plane_sigma_m = 0.02;
  const std::vector<std::string> cameras = ParseCameraNames(args.cameras);
  const CameraRig rig = DatasetCameraRig(dataset, cameras, args.odometry);
  Localizer localizer(map, rig, options);

  const size_t count = dataset.frames.size();
  RunReport report;
  int bad_frames = 0;
  for (size_t i = 0; i < count; ++i) {
    try {
      report.Add(localizer.Process(
          MakeFrameInput(dataset, i, args, cameras, rig, options.max_rig_skew_ns, blackout)));
    } catch (const InputError& e) {
      ++bad_frames;
      std::fprintf(stderr, "visloc localize: frame %zu skipped: %s\n", i, e.what());
      continue;
    }
    if (ShowProgress() && !args.json) {
      std::fprintf(stderr, "\r%-70s", report.ProgressLine(count).c_str());
    }
  }
  if (ShowProgress() && !args.json) std::fprintf(stderr, "\n");
  if (!args.trajectory_path.empty()) {
    WriteTum(args.trajectory_path, InFrame(args.frame, map->map(), report.PosedTrajectory()));
  }
  if (!args.stats_path.empty()) report.WriteStatsCsv(args.stats_path);
  const Trajectory* gt = ground_truth.empty() ? nullptr : &ground_truth;
  if (args.json) {
    JsonWriter json;
    json.BeginObject().Field("map_points", static_cast<int64_t>(map->point_count()));
    json.Field("mode", args.mode).Field("bad_frames", static_cast<int64_t>(bad_frames));
    report.WriteSummaryJson(json, gt);
    json.EndObject();
    std::cout << json.str() << "\n";
  } else {
    std::printf("map %s: %zu keyframes, %zu points; mode %s%s\n", args.map_path.c_str(),
                map->keyframe_count(), map->point_count(), args.mode.c_str(),
                args.odometry ? ", odometry fused" : "");
    report.PrintSummary(stdout, gt);
    if (bad_frames > 0) std::printf("%d frames skipped (see above)\n", bad_frames);
  }
  return 0;
}

}  // namespace visloc::cli
