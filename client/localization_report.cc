#include "client/localization_report.h"

#include <algorithm>
#include <array>
#include <map>
#include <utility>

#include "core/util/args.h"
#include "core/util/check.h"
#include "core/util/strings.h"
#include "core/util/text_file.h"

namespace visloc::cli {
namespace {

// The position covariance's upper triangle (map frame, m^2), as the stats CSV's last columns.
constexpr std::array<const char*, 6> kPositionCovarianceColumns = {
    "position_cov_xx_m2", "position_cov_xy_m2", "position_cov_xz_m2",
    "position_cov_yy_m2", "position_cov_yz_m2", "position_cov_zz_m2"};
constexpr std::array<std::pair<int, int>, 6> kPositionCovarianceEntries = {
    {{0, 0}, {0, 1}, {0, 2}, {1, 1}, {1, 2}, {2, 2}}};

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

double LatencyPercentile(std::vector<double> values, double fraction) {
  if (values.empty()) return 0.0;
  std::sort(values.begin(), values.end());
  // The epsilon keeps 0.99 * 100 at rank 99 (0.99 is a little below itself in binary).
  const size_t rank = static_cast<size_t>(fraction * static_cast<double>(values.size()) + 1e-9);
  return values[std::min(values.size() - 1, rank)];
}

std::string StatsCsvHeader() {
  std::string header =
      "timestamp_ns,status,source,features,predicted,putatives,inliers,inlier_ratio,"
      "ransac_iterations,reproj_rmse_px";
  for (const auto& [name, value] : StepColumns({})) header += StrCat(",", name);
  // Columns are only ever added at the end.
  header +=
      ",relocalization,relocalization_keyframe,position_sigma_m,relocalization_feature_passes";
  for (const char* name : kPositionCovarianceColumns) header += StrCat(",", name);
  // A rig's cameras, each a ';'-separated list in the rig's order (empty for one camera).
  header += ",camera_features,camera_putatives,camera_inliers";
  return header;
}

std::string StatsCsvRow(const LocalizationResult& r) {
  const FrameStats& s = r.stats;
  std::string row = StrCat(r.timestamp_ns, ",", TrackingStatusName(r.status), ",",
                           PoseSourceName(r.source), ",", s.features, ",", s.predicted, ",",
                           s.putatives, ",", s.inliers, ",", FormatFixed(s.inlier_ratio, 4), ",",
                           s.ransac_iterations, ",", FormatFixed(s.reproj_rmse_px, 4));
  for (const auto& [name, value] : StepColumns(s.times)) row += "," + FormatFixed(value, 4);
  row +=
      StrCat(",", RelocalizationKindName(r.relocalization.kind), ",", r.relocalization.keyframe,
             ",", FormatFixed(r.PositionSigmaPerAxisM(), 5), ",", r.relocalization.feature_passes);
  const Eigen::Matrix3d covariance = r.PositionCovarianceInMap();
  for (const auto& [a, b] : kPositionCovarianceEntries) row += StrCat(",", covariance(a, b));
  const auto per_camera = [&](int PoseFix::CameraSupport::*field) {
    std::string list;
    for (const PoseFix::CameraSupport& camera : s.cameras) {
      list += StrCat(list.empty() ? "" : ";", camera.*field);
    }
    return list;
  };
  row += StrCat(",", per_camera(&PoseFix::CameraSupport::features), ",",
                per_camera(&PoseFix::CameraSupport::putatives), ",",
                per_camera(&PoseFix::CameraSupport::inliers));
  return row;
}

std::map<int64_t, Eigen::Matrix3d> ReadPositionCovariances(const std::string& path) {
  const std::vector<TextLine> lines = ReadTextLines(path);
  if (lines.empty()) throw InputError(path + ": empty, expected a stats CSV header");
  const std::vector<std::string> header = Split(lines[0].text, ',');
  const auto sigma = std::find(header.begin(), header.end(), "position_sigma_m");
  if (header.empty() || header[0] != "timestamp_ns" || sigma == header.end()) {
    throw InputError(path + ": not a visloc stats CSV (no timestamp_ns and position_sigma_m)");
  }
  std::vector<size_t> entry_columns;
  for (const char* name : kPositionCovarianceColumns) {
    const auto found = std::find(header.begin(), header.end(), name);
    if (found != header.end()) entry_columns.push_back(static_cast<size_t>(found - header.begin()));
  }
  // A CSV from before the covariance columns: an isotropic covariance from the sigma.
  const bool isotropic = entry_columns.size() != kPositionCovarianceEntries.size();
  std::map<int64_t, Eigen::Matrix3d> covariances;
  for (size_t l = 1; l < lines.size(); ++l) {
    if (lines[l].text.empty()) continue;
    const DataRow row{lines[l].number, Split(lines[l].text, ',')};
    RequireFieldCount(path, row, header.size());
    Eigen::Matrix3d& covariance = covariances[FieldAsInt64(path, row, 0)];
    if (isotropic) {
      const double sigma_m = FieldAsDouble(path, row, static_cast<size_t>(sigma - header.begin()));
      covariance = Eigen::Matrix3d::Identity() * sigma_m * sigma_m;
      continue;
    }
    for (size_t i = 0; i < entry_columns.size(); ++i) {
      const auto [a, b] = kPositionCovarianceEntries[i];
      covariance(a, b) = covariance(b, a) = FieldAsDouble(path, row, entry_columns[i]);
    }
  }
  return covariances;
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

namespace {

// Everything the printed and the JSON summaries report, computed once.
struct Summary {
  size_t frames = 0;
  size_t visual = 0;  // Frames with a visual fix.
  size_t posed = 0;   // Frames with any pose (motion bridging included).
  std::map<std::string, int64_t> by_status;
  ErrorStats inliers, inlier_ratio, ransac_iterations;  // Over frames with a visual fix.
  std::vector<StepSummary> steps;
  std::optional<GroundTruthErrors> errors, bridged;
};

Summary Summarize(const std::vector<LocalizationResult>& results, const Trajectory* ground_truth) {
  Summary summary;
  summary.frames = results.size();
  std::vector<double> inliers, ratios, iterations;
  for (const LocalizationResult& r : results) {
    ++summary.by_status[TrackingStatusName(r.status)];
    summary.posed += r.has_pose;
    if (!VisualFix(r)) continue;
    ++summary.visual;
    inliers.push_back(r.stats.inliers);
    ratios.push_back(r.stats.inlier_ratio);
    iterations.push_back(r.stats.ransac_iterations);
  }
  summary.inliers = ComputeErrorStats(inliers);
  summary.inlier_ratio = ComputeErrorStats(ratios);
  summary.ransac_iterations = ComputeErrorStats(iterations);
  summary.steps = SummarizeSteps(results);
  if (ground_truth) {
    summary.errors = CompareWithGroundTruth(results, *ground_truth);
    summary.bridged = CompareWithGroundTruth(results, *ground_truth, PoseSource::kMotion);
  }
  return summary;
}

}  // namespace

std::vector<StepSummary> SummarizeSteps(const std::vector<LocalizationResult>& results) {
  std::vector<StepSummary> steps;
  for (const auto& [column, unused] : StepColumns({})) {
    std::string name = column;
    steps.push_back({name.substr(0, name.size() - 3), {}});  // Drop "_ms".
  }
  std::vector<std::vector<double>> values(steps.size());
  for (const LocalizationResult& r : results) {
    const auto columns = StepColumns(r.stats.times);
    for (size_t c = 0; c < columns.size(); ++c) values[c].push_back(columns[c].second);
  }
  for (size_t c = 0; c < steps.size(); ++c) steps[c].ms = ComputeErrorStats(values[c]);
  return steps;
}

void RunReport::PrintSummary(std::FILE* out, const Trajectory* ground_truth) const {
  const Summary s = Summarize(results_, ground_truth);
  std::fprintf(out, "frames %zu: localized %zu (%.1f%%) by vision, %zu with a pose;", s.frames,
               s.visual, s.frames ? 100.0 * s.visual / s.frames : 0.0, s.posed);
  for (const auto& [status, count] : s.by_status) {
    std::fprintf(out, " %s %lld", status.c_str(), static_cast<long long>(count));
  }
  std::fprintf(out, "\n");
  std::fprintf(out,
               "localized frames: inliers median %.0f, inlier ratio median %.3f, RANSAC "
               "iterations median %.0f (max %.0f)\n",
               s.inliers.median, s.inlier_ratio.median, s.ransac_iterations.median,
               s.ransac_iterations.max);
  std::fprintf(out, "time per frame (ms), median / p95:");
  for (const StepSummary& step : s.steps) {
    std::fprintf(out, " %s %.2f/%.2f", step.name.c_str(), step.ms.median, step.ms.p95);
  }
  std::fprintf(out, "\n");
  if (s.errors) {
    std::fprintf(out,
                 "error against ground truth (%zu posed frames): position median %.2f cm, max "
                 "%.2f cm; rotation median %.3f deg, max %.3f deg\n",
                 s.errors->compared, 100 * s.errors->position_m.median,
                 100 * s.errors->position_m.max, s.errors->rotation_deg.median,
                 s.errors->rotation_deg.max);
  }
  if (s.bridged && s.bridged->compared > 0) {
    std::fprintf(out,
                 "  of which bridged by motion alone (%zu frames): position median %.2f cm, "
                 "max %.2f cm; rotation max %.3f deg\n",
                 s.bridged->compared, 100 * s.bridged->position_m.median,
                 100 * s.bridged->position_m.max, s.bridged->rotation_deg.max);
  }
}

void RunReport::WriteSummaryJson(JsonWriter& json, const Trajectory* ground_truth) const {
  const Summary s = Summarize(results_, ground_truth);
  const double n = static_cast<double>(std::max<size_t>(1, s.frames));
  json.Field("frames", static_cast<int64_t>(s.frames))
      .Field("localized_fraction", s.visual / n)
      .Field("posed_fraction", s.posed / n);
  json.Key("statuses").BeginObject();
  for (const auto& [status, count] : s.by_status) json.Field(status, count);
  json.EndObject();
  json.Key("ms_per_frame").BeginObject();
  for (const StepSummary& step : s.steps) {
    json.Key(step.name + "_ms")
        .BeginObject()
        .Field("median", step.ms.median)
        .Field("p95", step.ms.p95)
        .EndObject();
  }
  json.EndObject();
  json.Field("inlier_ratio_median", s.inlier_ratio.median)
      .Field("inliers_median", s.inliers.median)
      .Field("ransac_iterations_median", s.ransac_iterations.median);
  if (s.errors) {
    json.Key("ground_truth")
        .BeginObject()
        .Field("compared", static_cast<int64_t>(s.errors->compared))
        .Field("position_median_m", s.errors->position_m.median)
        .Field("position_max_m", s.errors->position_m.max)
        .Field("rotation_median_deg", s.errors->rotation_deg.median)
        .Field("rotation_max_deg", s.errors->rotation_deg.max)
        .Field("bridged_compared", static_cast<int64_t>(s.bridged->compared))
        .Field("bridged_position_max_m", s.bridged->position_m.max)
        .Field("bridged_position_median_m", s.bridged->position_m.median)
        .EndObject();
  }
}

Trajectory InFrame(const std::string& frame, const Map& map, Trajectory trajectory) {
  if (frame == "map") return trajectory;
  if (frame != "site") throw UsageError("--frame must be map or site, not '" + frame + "'");
  const std::optional<Rigid3d> site_from_map = SiteFromMap(map.metadata);
  if (!site_from_map) {
    throw InputError(StrCat("map '", map.metadata.name,
                            "' records no up, so it has no site frame: write --frame map, or "
                            "rebuild it (map build finds up) or tie it with map align"));
  }
  for (StampedPose& pose : trajectory) pose.pose = *site_from_map * pose.pose;
  return trajectory;
}

}  // namespace visloc::cli
