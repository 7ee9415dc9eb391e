#include "client/localization_report.h"

#include <map>

#include "core/eval/trajectory_eval.h"
#include "core/util/check.h"
#include "core/util/strings.h"
#include "core/util/text_file.h"

namespace visloc::cli {
namespace {

bool VisualFix(const LocalizationResult& r) {
  return r.has_pose &&
         (r.source == PoseSource::kTracking || r.source == PoseSource::kRelocalization);
}

// Per-step timings by name, in CSV column order.
std::vector<std::pair<const char*, double>> StepColumns(const StepTimings& t) {
  return {{"detect_ms", t.detect_ms},       {"describe_ms", t.describe_ms},
          {"undistort_ms", t.undistort_ms}, {"predict_ms", t.predict_ms},
          {"project_ms", t.project_ms},     {"match_ms", t.match_ms},
          {"pose_ms", t.pose_ms},           {"relocalize_ms", t.relocalize_ms},
          {"total_ms", t.total_ms}};
}

ErrorStats StatsOf(const std::vector<LocalizationResult>& results,
                   double (*value)(const LocalizationResult&), bool posed_only = false) {
  std::vector<double> values;
  for (const LocalizationResult& r : results) {
    if (!posed_only || VisualFix(r)) values.push_back(value(r));
  }
  return ComputeErrorStats(values);
}

struct GroundTruthErrors {
  ErrorStats position_m;
  ErrorStats rotation_deg;
  size_t compared = 0;
};

// Errors of the posed frames (or only those whose pose came from `only`).
GroundTruthErrors CompareWithGroundTruth(const std::vector<LocalizationResult>& results,
                                         const Trajectory& ground_truth,
                                         std::optional<PoseSource> only = std::nullopt) {
  std::vector<double> position, rotation;
  for (const LocalizationResult& r : results) {
    if (!r.has_pose || (only && r.source != *only)) continue;
    const std::optional<Rigid3d> gt = InterpolateAt(ground_truth, r.timestamp_ns, SecondsToNs(0.1));
    if (!gt) continue;
    position.push_back((gt->translation - r.map_from_cam.translation).norm());
    rotation.push_back(RotationAngleDeg(gt->rotation.inverse() * r.map_from_cam.rotation));
  }
  GroundTruthErrors errors;
  errors.compared = position.size();
  errors.position_m = ComputeErrorStats(position);
  errors.rotation_deg = ComputeErrorStats(rotation);
  return errors;
}

}  // namespace

std::string StatsCsvHeader() {
  std::string header =
      "timestamp_ns,status,source,features,predicted,putatives,inliers,inlier_ratio,"
      "ransac_iterations,reproj_rmse_px";
  for (const auto& [name, value] : StepColumns({})) header += StrCat(",", name);
  header += ",relocalization,relocalization_keyframe,position_sigma_m";
  return header;
}

std::string StatsCsvRow(const LocalizationResult& r) {
  const FrameStats& s = r.stats;
  std::string row = StrCat(r.timestamp_ns, ",", TrackingStatusName(r.status), ",",
                           PoseSourceName(r.source), ",", s.features, ",", s.predicted, ",",
                           s.putatives, ",", s.inliers, ",", FormatFixed(s.inlier_ratio, 4), ",",
                           s.ransac_iterations, ",", FormatFixed(s.reproj_rmse_px, 4));
  for (const auto& [name, value] : StepColumns(s.times)) row += "," + FormatFixed(value, 4);
  const double sigma =
      r.has_pose ? std::sqrt(std::max(0.0, r.covariance.topLeftCorner<3, 3>().trace())) : 0.0;
  row += StrCat(",", RelocalizationKindName(r.relocalization.kind), ",", r.relocalization.keyframe,
                ",", FormatFixed(sigma, 5));
  return row;
}

void RunReport::Add(const LocalizationResult& result) { results_.push_back(result); }

Trajectory RunReport::PosedTrajectory() const {
  Trajectory trajectory;
  for (const LocalizationResult& r : results_) {
    if (r.has_pose) trajectory.push_back({r.timestamp_ns, r.map_from_cam});
  }
  return trajectory;
}

void RunReport::WriteStatsCsv(const std::string& path) const {
  std::string text = StatsCsvHeader() + "\n";
  for (const LocalizationResult& r : results_) text += StatsCsvRow(r) + "\n";
  WriteFileAtomically(path, text);
}

std::string RunReport::ProgressLine(size_t frame_count) const {
  if (results_.empty()) return "";
  const LocalizationResult& r = results_.back();
  return StrCat("frame ", results_.size(), "/", frame_count, "  ", TrackingStatusName(r.status),
                "  inliers ", r.stats.inliers, "/", r.stats.putatives, "  ",
                FormatFixed(r.stats.times.total_ms, 1), " ms");
}

void RunReport::PrintSummary(std::FILE* out, const Trajectory* ground_truth) const {
  const size_t n = results_.size();
  std::map<std::string, int> by_status;
  size_t visual = 0, posed = 0;
  for (const LocalizationResult& r : results_) {
    ++by_status[TrackingStatusName(r.status)];
    visual += VisualFix(r);
    posed += r.has_pose;
  }
  std::fprintf(out, "frames %zu: localized %zu (%.1f%%) by vision, %zu with a pose;", n, visual,
               n ? 100.0 * visual / n : 0.0, posed);
  for (const auto& [status, count] : by_status) std::fprintf(out, " %s %d", status.c_str(), count);
  std::fprintf(out, "\n");
  const ErrorStats inliers = StatsOf(
      results_, [](const LocalizationResult& r) { return static_cast<double>(r.stats.inliers); },
      true);
  const ErrorStats ratio = StatsOf(
      results_, [](const LocalizationResult& r) { return r.stats.inlier_ratio; }, true);
  const ErrorStats iterations = StatsOf(
      results_,
      [](const LocalizationResult& r) { return static_cast<double>(r.stats.ransac_iterations); },
      true);
  std::fprintf(out,
               "localized frames: inliers median %.0f, inlier ratio median %.3f, RANSAC "
               "iterations median %.0f (max %.0f)\n",
               inliers.median, ratio.median, iterations.median, iterations.max);
  std::fprintf(out, "time per frame (ms), median / p95:");
  std::vector<std::vector<double>> columns(StepColumns({}).size());
  for (const LocalizationResult& r : results_) {
    const auto steps = StepColumns(r.stats.times);
    for (size_t c = 0; c < steps.size(); ++c) columns[c].push_back(steps[c].second);
  }
  const auto names = StepColumns({});
  for (size_t c = 0; c < columns.size(); ++c) {
    const ErrorStats stats = ComputeErrorStats(columns[c]);
    std::string name = names[c].first;
    name.resize(name.size() - 3);  // Drop "_ms".
    std::fprintf(out, " %s %.2f/%.2f", name.c_str(), stats.median, stats.p95);
  }
  std::fprintf(out, "\n");
  if (ground_truth) {
    const GroundTruthErrors errors = CompareWithGroundTruth(results_, *ground_truth);
    std::fprintf(out,
                 "error against ground truth (%zu posed frames): position median %.2f cm, max "
                 "%.2f cm; rotation median %.3f deg, max %.3f deg\n",
                 errors.compared, 100 * errors.position_m.median, 100 * errors.position_m.max,
                 errors.rotation_deg.median, errors.rotation_deg.max);
    const GroundTruthErrors bridged =
        CompareWithGroundTruth(results_, *ground_truth, PoseSource::kMotion);
    if (bridged.compared > 0) {
      std::fprintf(out,
                   "  of which bridged by motion alone (%zu frames): position median %.2f cm, "
                   "max %.2f cm; rotation max %.3f deg\n",
                   bridged.compared, 100 * bridged.position_m.median, 100 * bridged.position_m.max,
                   bridged.rotation_deg.max);
    }
  }
}

void RunReport::WriteSummaryJson(JsonWriter& json, const Trajectory* ground_truth) const {
  size_t visual = 0, posed = 0;
  std::map<std::string, int64_t> by_status;
  for (const LocalizationResult& r : results_) {
    ++by_status[TrackingStatusName(r.status)];
    visual += VisualFix(r);
    posed += r.has_pose;
  }
  const double n = static_cast<double>(std::max<size_t>(1, results_.size()));
  json.Field("frames", static_cast<int64_t>(results_.size()))
      .Field("localized_fraction", visual / n)
      .Field("posed_fraction", posed / n);
  json.Key("statuses").BeginObject();
  for (const auto& [status, count] : by_status) json.Field(status, count);
  json.EndObject();
  json.Key("ms_per_frame").BeginObject();
  const auto names = StepColumns({});
  for (size_t c = 0; c < names.size(); ++c) {
    std::vector<double> values;
    for (const LocalizationResult& r : results_)
      values.push_back(StepColumns(r.stats.times)[c].second);
    const ErrorStats stats = ComputeErrorStats(values);
    json.Key(names[c].first)
        .BeginObject()
        .Field("median", stats.median)
        .Field("p95", stats.p95)
        .EndObject();
  }
  json.EndObject();
  json.Field("inlier_ratio_median",
             StatsOf(
                 results_, [](const LocalizationResult& r) { return r.stats.inlier_ratio; }, true)
                 .median);
  json.Field(
      "inliers_median",
      StatsOf(
          results_,
          [](const LocalizationResult& r) { return static_cast<double>(r.stats.inliers); }, true)
          .median);
  json.Field("ransac_iterations_median",
             StatsOf(
                 results_,
                 [](const LocalizationResult& r) {
                   return static_cast<double>(r.stats.ransac_iterations);
                 },
                 true)
                 .median);
  if (ground_truth) {
    const GroundTruthErrors errors = CompareWithGroundTruth(results_, *ground_truth);
    json.Key("ground_truth")
        .BeginObject()
        .Field("compared", static_cast<int64_t>(errors.compared))
        .Field("position_median_m", errors.position_m.median)
        .Field("position_max_m", errors.position_m.max)
        .Field("rotation_median_deg", errors.rotation_deg.median)
        .Field("rotation_max_deg", errors.rotation_deg.max);
    const GroundTruthErrors bridged =
        CompareWithGroundTruth(results_, *ground_truth, PoseSource::kMotion);
    json.Field("bridged_compared", static_cast<int64_t>(bridged.compared))
        .Field("bridged_position_max_m", bridged.position_m.max)
        .Field("bridged_position_median_m", bridged.position_m.median)
        .EndObject();
  }
}

}  // namespace visloc::cli
