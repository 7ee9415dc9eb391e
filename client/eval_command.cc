#include <cstdio>
#include <iostream>
#include <map>
#include <optional>

#include "client/commands.h"
#include "client/localization_report.h"
#include "core/eval/trajectory_eval.h"
#include "core/util/args.h"
#include "core/util/check.h"
#include "core/util/json.h"
#include "core/util/strings.h"
#include "dataset/tum.h"

namespace visloc::cli {
namespace {

void WriteStats(JsonWriter& json, const std::string& key, const ErrorStats& stats) {
  json.Key(key)
      .BeginObject()
      .Field("count", static_cast<int64_t>(stats.count))
      .Field("rmse", stats.rmse)
      .Field("mean", stats.mean)
      .Field("median", stats.median)
      .Field("std", stats.std_dev)
      .Field("min", stats.min)
      .Field("max", stats.max)
      .EndObject();
}

void WritePoseErrors(JsonWriter& json, const std::string& key, const PoseErrors& errors) {
  json.Key(key).BeginObject();
  WriteStats(json, "translation_m", errors.translation_m);
  WriteStats(json, "rotation_deg", errors.rotation_deg);
  json.EndObject();
}

void WriteConsistency(JsonWriter& json, const ConsistencyEvaluation& c) {
  json.Key("consistency")
      .BeginObject()
      .Field("compared", static_cast<int64_t>(c.compared))
      .Field("beyond_3_sigma", c.beyond_3_sigma)
      .Field("beyond_6_sigma", c.beyond_6_sigma);
  WriteStats(json, "normalized_error", c.normalized_error);
  json.EndObject();
}

std::string ToJson(const TrajectoryEvaluation& eval, const EvalOptions& options,
                   const std::optional<ConsistencyEvaluation>& consistency) {
  JsonWriter json;
  json.BeginObject()
      .Field("gt_poses", static_cast<int64_t>(eval.gt_poses))
      .Field("est_poses", static_cast<int64_t>(eval.est_poses))
      .Field("matched_poses", static_cast<int64_t>(eval.matched_poses))
      .Field("coverage", eval.coverage);
  WritePoseErrors(json, "ate", eval.ate);
  WriteStats(json, "ate_per_distance", eval.ate_per_distance);
  if (eval.ate_aligned) {
    WritePoseErrors(json, "ate_aligned", *eval.ate_aligned);
    const Eigen::Vector3d& t = eval.gt_from_est.translation;
    const Eigen::Quaterniond& q = eval.gt_from_est.rotation;
    json.Key("gt_from_est")
        .BeginObject()
        .Field("x", t.x())
        .Field("y", t.y())
        .Field("z", t.z())
        .Field("qw", q.w())
        .Field("qx", q.x())
        .Field("qy", q.y())
        .Field("qz", q.z())
        .EndObject();
  }
  json.Field("rpe_delta_s", options.rpe_delta_s);
  WritePoseErrors(json, "rpe", eval.rpe);
  if (consistency) WriteConsistency(json, *consistency);
  json.EndObject();
  return json.str();
}

void PrintRow(const std::string& label, const ErrorStats& stats, double scale, const char* unit) {
  std::printf("  %-22s rmse %8.4f  median %8.4f  max %8.4f %s  (n=%zu)\n", label.c_str(),
              stats.rmse * scale, stats.median * scale, stats.max * scale, unit, stats.count);
}

void PrintHuman(const TrajectoryEvaluation& eval, const EvalOptions& options,
                const std::optional<ConsistencyEvaluation>& consistency) {
  std::printf("poses: %zu ground truth, %zu estimated, %zu associated (coverage %.1f%%)\n",
              eval.gt_poses, eval.est_poses, eval.matched_poses, 100.0 * eval.coverage);
  std::printf("ATE in the map frame (no alignment):\n");
  PrintRow("translation", eval.ate.translation_m, 100.0, "cm");
  PrintRow("rotation", eval.ate.rotation_deg, 1.0, "deg");
  if (eval.ate_per_distance.count > 0) {
    PrintRow("per distance travelled", eval.ate_per_distance, 100.0, "%");
  }
  if (eval.ate_aligned) {
    std::printf("ATE after SE(3) alignment:\n");
    PrintRow("translation", eval.ate_aligned->translation_m, 100.0, "cm");
    PrintRow("rotation", eval.ate_aligned->rotation_deg, 1.0, "deg");
  }
  std::printf("RPE over %.3g s:\n", options.rpe_delta_s);
  PrintRow("translation", eval.rpe.translation_m, 100.0, "cm");
  PrintRow("rotation", eval.rpe.rotation_deg, 1.0, "deg");
  if (consistency) {
    std::printf(
        "covariance: position error in sigmas (Mahalanobis) over %zu poses: median %.2f (honest: "
        "1.54), "
        "%.1f%% beyond 3 sigma (honest: 2.9%%), %.1f%% beyond 6, max %.1f\n",
        consistency->compared, consistency->normalized_error.median,
        100.0 * consistency->beyond_3_sigma, 100.0 * consistency->beyond_6_sigma,
        consistency->normalized_error.max);
  }
}

std::string ToJson(const TrajectorySpread& spread) {
  JsonWriter json;
  json.BeginObject().Field("poses", static_cast<int64_t>(spread.poses));
  json.Key("mean_position")
      .BeginObject()
      .Field("x", spread.mean_position.x())
      .Field("y", spread.mean_position.y())
      .Field("z", spread.mean_position.z())
      .EndObject();
  json.Key("spread").BeginObject();
  WriteStats(json, "position_m", spread.position_m);
  WriteStats(json, "rotation_deg", spread.rotation_deg);
  json.EndObject().EndObject();
  return json.str();
}

void PrintHuman(const TrajectorySpread& spread) {
  std::printf("%zu poses about (%.4f, %.4f, %.4f) m:\n", spread.poses, spread.mean_position.x(),
              spread.mean_position.y(), spread.mean_position.z());
  PrintRow("position", spread.position_m, 1000.0, "mm");
  PrintRow("rotation", spread.rotation_deg, 1.0, "deg");
}

}  // namespace

int RunEval(const Args& args) {
  std::string gt_path, est_path, stats_path;
  EvalOptions options;
  bool json = false;
  ArgParser parser("visloc eval",
                   "Compares an estimated TUM trajectory with ground truth: ATE (no alignment, and "
                   "with --align after SE(3) Umeyama alignment), RPE over --delta seconds, and "
                   "coverage (share of ground-truth poses with an estimate). With --spread and no "
                   "ground truth: how far the poses scatter about their mean (the jitter of a "
                   "camera that stands still).");
  bool spread = false;
  parser.AddFlag("gt", &gt_path, "ground-truth TUM file (required unless --spread)");
  parser.AddFlag("est", &est_path, "estimated TUM file", /*required=*/true);
  parser.AddSwitch("spread", &spread, "deviations of the poses from their mean pose");
  parser.AddSwitch("align", &options.align, "also report ATE after SE(3) alignment");
  parser.AddSwitch("gt-origin-first", &options.gt_origin_first,
                   "take the ground truth relative to its first pose (a recording's ground truth "
                   "against a map built from its first frame)");
  parser.AddFlag("stats", &stats_path,
                 "the run's stats CSV: also check its position covariances against the errors");
  parser.AddFlag("delta", &options.rpe_delta_s, "RPE interval in seconds");
  parser.AddFlag("max-dt", &options.max_time_diff_s, "association tolerance in seconds");
  parser.AddSwitch("json", &json, "print one JSON object");
  if (!parser.Parse(args, std::cout)) return 0;
  if (options.rpe_delta_s <= 0) throw UsageError("--delta must be positive");
  if (options.max_time_diff_s < 0) throw UsageError("--max-dt must not be negative");
  if (spread && (!gt_path.empty() || !stats_path.empty())) {
    throw UsageError("--spread takes no --gt or --stats");
  }
  if (!spread && gt_path.empty()) throw UsageError("missing --gt");
  const Trajectory est = ReadTum(est_path);
  if (spread) {
    if (est.empty()) throw InputError(est_path + ": no poses");
    const TrajectorySpread result = ComputeSpread(est);
    if (json) {
      std::cout << ToJson(result) << "\n";
    } else {
      PrintHuman(result);
    }
    return 0;
  }
  const Trajectory gt = ReadTum(gt_path);
  if (gt.empty()) throw InputError(gt_path + ": no poses");
  const TrajectoryEvaluation eval = EvaluateTrajectory(gt, est, options);
  std::optional<ConsistencyEvaluation> consistency;
  if (!stats_path.empty()) {
    const std::map<int64_t, Eigen::Matrix3d> covariances = ReadPositionCovariances(stats_path);
    std::vector<Eigen::Matrix3d> position_covariance_m2;
    for (const StampedPose& p : est) {
      const auto it = covariances.find(p.timestamp_ns);
      position_covariance_m2.push_back(it == covariances.end() ? Eigen::Matrix3d::Zero()
                                                               : it->second);
    }
    consistency = EvaluateConsistency(gt, est, position_covariance_m2, options);
  }
  if (json) {
    std::cout << ToJson(eval, options, consistency) << "\n";
  } else {
    PrintHuman(eval, options, consistency);
  }
  return 0;
}

}  // namespace visloc::cli
