// `visloc dataset VERB`: what a recorded sequence holds before it is used. `check` tells
// whether a stereo rig will map and, if not, why (mapping/dataset_check.h); `import` turns a
// ROS bag into a sequence (dataset_import_command.cc).

#include <cmath>
#include <cstdio>
#include <iostream>

#include "client/commands.h"
#include "client/outcome.h"
#include "client/subcommands.h"
#include "core/util/args.h"
#include "core/util/check.h"
#include "core/util/json.h"
#include "core/util/strings.h"
#include "dataset/tum.h"
#include "mapping/dataset_check.h"

namespace visloc::cli {
namespace {

void PrintCamera(const char* name, const CameraInfo& info) {
  const Eigen::Vector3d& t = info.body_from_cam.translation;
  std::printf("%s: %s\n", name, ToString(info.camera).c_str());
  std::printf("      T_BS: translation (%.4f, %.4f, %.4f) m, rotation %.2f deg\n", t.x(), t.y(),
              t.z(), RotationAngleDeg(info.body_from_cam.rotation));
}

void PrintHuman(const std::string& dir, const Dataset& dataset,
                const mapping::DatasetCheck& check) {
  std::printf("%s (%s): %d frames over %.2f s", dir.c_str(), ToString(dataset.format).c_str(),
              check.frames, check.duration_s);
  if (check.median_period_s > 0) {
    std::printf(" (%.1f Hz), largest gap %.0f ms", 1.0 / check.median_period_s,
                check.max_gap_s * 1e3);
  }
  std::printf("; %d left and %d right images unpaired\n", check.pairing.unpaired_left,
              check.pairing.unpaired_right);
  PrintCamera("cam0", dataset.left);
  if (!dataset.right) {
    std::printf("cam1: none\n");
  } else {
    PrintCamera("cam1", *dataset.right);
    std::printf("rectified pair: focal %.1f px, baseline %.4f m, left camera turned %.2f deg\n",
                check.rectified_focal_px, check.baseline_m, check.rectification_deg);
    std::printf(
        "epipolar residual: row difference of %d left/right descriptor matches after "
        "rectification: median %.2f px, 95th percentile %.2f px\n",
        check.descriptor_matches, check.row_difference_median_px, check.row_difference_p95_px);
    std::printf(
        "stereo: %.0f of %.0f left keypoints matched per frame (median); depth %.2f m "
        "(median), %.2f - %.2f m (5th - 95th percentile)\n",
        check.stereo_matches_median, check.keypoints_median, check.depth_median_m, check.depth_p5_m,
        check.depth_p95_m);
    std::printf("  %6s %10s %9s %8s %6s %9s %8s %10s\n", "frame", "time s", "keypoints", "matched",
                "weak", "ambiguous", "refined", "row px");
    for (const mapping::SampledFrame& s : check.samples) {
      const auto& st = s.check.stereo;
      std::printf("  %6d %10.3f %9d %8d %6d %9d %8d %10.2f\n", s.index,
                  (s.timestamp_ns - dataset.frames.front().timestamp_ns) * 1e-9, st.keypoints,
                  st.matched, st.weak, st.ambiguous, st.refine_rejected,
                  mapping::Quantile(s.check.row_difference_px, 0.5));
    }
  }
  for (const std::string& w : check.warnings) std::printf("warning: %s\n", w.c_str());
  for (const std::string& p : check.problems) std::printf("problem: %s\n", p.c_str());
  std::printf("%s\n", check.ok() ? "this rig maps" : "this rig would not map");
}

// NaN (nothing measured) is written as null.
JsonWriter& Number(JsonWriter& json, const std::string& key, double value) {
  json.Key(key);
  return std::isfinite(value) ? json.Value(value) : json.Value(std::string("null"));
}

std::string ToJson(const std::string& dir, const Dataset& dataset,
                   const mapping::DatasetCheck& check) {
  JsonWriter json;
  json.BeginObject()
      .Field("dataset", dir)
      .Field("format", ToString(dataset.format))
      .Field("ok", check.ok())
      .Field("frames", check.frames)
      .Field("duration_s", check.duration_s)
      .Field("median_period_s", check.median_period_s)
      .Field("max_gap_s", check.max_gap_s)
      .Field("long_gaps", check.long_gaps)
      .Field("unpaired_left", check.pairing.unpaired_left)
      .Field("unpaired_right", check.pairing.unpaired_right)
      .Field("rectified_focal_px", check.rectified_focal_px)
      .Field("baseline_m", check.baseline_m)
      .Field("descriptor_matches", check.descriptor_matches);
  Number(json, "row_difference_median_px", check.row_difference_median_px);
  Number(json, "row_difference_p95_px", check.row_difference_p95_px);
  Number(json, "disparity_median_px", check.disparity_median_px);
  Number(json, "stereo_matches_median", check.stereo_matches_median);
  Number(json, "keypoints_median", check.keypoints_median);
  Number(json, "depth_p5_m", check.depth_p5_m);
  Number(json, "depth_median_m", check.depth_median_m);
  Number(json, "depth_p95_m", check.depth_p95_m);
  json.Key("samples").BeginArray();
  for (const mapping::SampledFrame& s : check.samples) {
    const auto& st = s.check.stereo;
    json.BeginObject()
        .Field("index", s.index)
        .Field("timestamp_ns", s.timestamp_ns)
        .Field("keypoints", st.keypoints)
        .Field("matched", st.matched)
        .Field("weak", st.weak)
        .Field("ambiguous", st.ambiguous)
        .Field("refine_rejected", st.refine_rejected)
        .Field("descriptor_matches", static_cast<int>(s.check.row_difference_px.size()));
    Number(json, "row_difference_median_px", mapping::Quantile(s.check.row_difference_px, 0.5));
    json.EndObject();
  }
  json.EndArray();
  json.Key("problems").BeginArray();
  for (const std::string& p : check.problems) json.Value(p);
  json.EndArray().Key("warnings").BeginArray();
  for (const std::string& w : check.warnings) json.Value(w);
  json.EndArray().EndObject();
  return json.str();
}

int RunCheck(const Args& args) {
  std::string dir, format, features = "harris_surf16";
  bool json = false;
  mapping::DatasetCheckOptions options;
  ArgParser parser("visloc dataset check",
                   "Tells whether a stereo dataset will map, before a build: both cameras' models, "
                   "the rectified baseline and focal length, the epipolar residual of left/right "
                   "matches after rectification, keypoints and stereo matches per frame, the depth "
                   "range, timestamp gaps and left/right pairing. Exits 1 with the reason when "
                   "the rig would not map.");
  parser.AddPositional("DIR", &dir, "dataset folder (EuRoC or KITTI layout)");
  parser.AddFlag("format", &format, "euroc or kitti (default: detected)");
  parser.AddFlag("features", &features, "harris_surf16 (the paper's) or orb, as map build");
  parser.AddFlag("frames", &options.sample_frames, "frames examined, spread over the sequence");
  parser.AddSwitch("json", &json, "print one JSON object");
  if (!parser.Parse(args, std::cout)) return 0;
  if (options.sample_frames < 1) throw UsageError("--frames must be at least 1");
  options.features = DefaultFeatureSettings(features);
  const Dataset dataset = ReadDataset(dir, ParseOptionalDatasetFormat(format));
  const bool progress = ShowProgress() && !json;
  const mapping::DatasetCheck check =
      mapping::CheckDataset(dataset, options, [&](int done, int total) {
        if (progress) std::fprintf(stderr, "\r\33[Kframe %d / %d", done, total);
      });
  if (progress) std::fprintf(stderr, "\r\33[K");
  if (json) {
    std::cout << ToJson(dir, dataset, check) << "\n";
  } else {
    PrintHuman(dir, dataset, check);
  }
  std::cout.flush();
  if (!check.ok()) throw InputError(check.problems.front());
  return 0;
}

int RunGroundTruth(const Args& args) {
  std::string dir, format, out;
  ArgParser parser("visloc dataset groundtruth",
                   "Writes a dataset's ground truth for its left camera at the frame times, as "
                   "TUM (what visloc eval --gt takes): KITTI's poses.txt, or EuRoC's "
                   "state_groundtruth_estimate0 moved from the body to cam0 by T_BS. Frames with "
                   "no ground truth within 50 ms are left out.");
  parser.AddPositional("DIR", &dir, "dataset folder (EuRoC or KITTI layout)");
  parser.AddFlag("format", &format, "euroc or kitti (default: detected)");
  parser.AddFlag("out", &out, "TUM file to write", /*required=*/true);
  bool json = false;
  parser.AddSwitch("json", &json, "print one JSON object");
  if (!parser.Parse(args, std::cout)) return 0;
  const Dataset dataset = ReadDataset(dir, ParseOptionalDatasetFormat(format));
  const Trajectory left_cam = dataset.GroundTruthLeftCam();
  if (left_cam.empty()) throw InputError(dir + ": no ground truth at the frames' times");
  WriteTum(out, left_cam);
  return PrintOutcome(json,
                      StrCat(left_cam.size(), " of ", dataset.frames.size(),
                             " frames' left camera poses -> ", out),
                      {{"out", out},
                       {"poses", static_cast<int64_t>(left_cam.size())},
                       {"frames", static_cast<int64_t>(dataset.frames.size())}});
}

}  // namespace

int RunDataset(const Args& args) {
  static const std::vector<Subcommand> kVerbs = {
      {"check", "will this stereo rig map? calibration, epipolar residual, stereo matches",
       RunCheck},
      {"import", "a ROS 1 or ROS 2 bag into an EuRoC-layout sequence", RunDatasetImport},
      {"groundtruth", "the left camera's ground truth at the frame times, as TUM", RunGroundTruth},
  };
  return DispatchSubcommand("visloc dataset VERB [options]", "Inspect datasets. Verbs:", kVerbs,
                            args);
}

}  // namespace visloc::cli
