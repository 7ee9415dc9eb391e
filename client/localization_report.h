#pragma once
// What `visloc localize` (in-process) and `visloc stream` (through the server) write and print
// about a run: the per-frame statistics CSV of product.md, the trajectory, and the summary.
// Both feed it core LocalizationResults, so their outputs are identical in form.

#include <cstdio>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "core/eval/trajectory_eval.h"
#include "core/geometry/trajectory.h"
#include "core/localization/localizer.h"
#include "core/util/json.h"

namespace visloc::cli {

// Median and 95th percentile of one per-frame step ("detect", ..., "total"), in CSV order.
struct StepSummary {
  std::string name;  // Without the "_ms" of its CSV column.
  ErrorStats ms;
};
std::vector<StepSummary> SummarizeSteps(const std::vector<LocalizationResult>& results);

// The value of `values` at rank floor(fraction n) of their ascending order (the last for
// fraction 1; 0 for none): the latency percentiles `visloc stream` and `visloc load` report.
double LatencyPercentile(std::vector<double> values, double fraction);

// The CSV header line (no newline) and one row per frame.
std::string StatsCsvHeader();
std::string StatsCsvRow(const LocalizationResult& result);

// The position covariance (map frame, m^2) of each frame of a stats CSV written by StatsCsvRow,
// by timestamp (ns): its position_cov_* columns, or in a CSV from before them its per-axis sigma
// as an isotropic one (zero without a pose). Throws InputError naming the file and line of a
// malformed row, or the file when it has no position_sigma_m column.
std::map<int64_t, Eigen::Matrix3d> ReadPositionCovariances(const std::string& path);

// Accumulates a run's results for the summary, the trajectory and the stats file.
class RunReport {
 public:
  void Add(const LocalizationResult& result);

  const std::vector<LocalizationResult>& results() const { return results_; }
  // Frames with a pose, as map_from_cam (the TUM output).
  Trajectory PosedTrajectory() const;
  void WriteStatsCsv(const std::string& path) const;

  // One live line for a terminal: frame, status, inliers, time.
  std::string ProgressLine(size_t frame_count) const;
  // The summary: share per status, per-step medians, relocalizations; with ground truth (map
  // frame), the position and rotation error of the posed frames.
  void PrintSummary(std::FILE* out, const Trajectory* ground_truth) const;
  void WriteSummaryJson(JsonWriter& json, const Trajectory* ground_truth) const;

 private:
  std::vector<LocalizationResult> results_;
};

// `trajectory` (map_from_cam) in the frame named by `--frame`: "map" as it is, "site" turned by
// the map's site_from_map (map.h SiteFromMap). Throws UsageError for another name and InputError
// for "site" on a map that records no up.
Trajectory InFrame(const std::string& frame, const Map& map, Trajectory trajectory);

}  // namespace visloc::cli
