// `visloc plot --map MAP.db --trajectory EST.tum [--stats S.csv] [--gt GT.tum] --out P.png|P.svg`
// `visloc plot --series --stats S.csv --out P.png`; `visloc plot --curves C.csv [--log-x] --out
// P.png`

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <limits>

#include "client/commands.h"
#include "client/outcome.h"
#include "client/plot.h"
#include "core/util/args.h"
#include "core/util/check.h"
#include "core/util/strings.h"
#include "core/util/text_file.h"
#include "dataset/tum.h"
#include "mapstore/map_store.h"

namespace visloc::cli {
namespace {

// Columns of a stats CSV written by localize or stream, by name; rows in file order. A frame
// without a pose has no inlier ratio or iterations worth plotting: those read as NaN.
struct StatsTable {
  std::vector<int64_t> timestamps;
  std::map<std::string, std::vector<double>> columns;
};

StatsTable ReadStats(const std::string& path, const std::vector<std::string>& wanted) {
  const std::vector<TextLine> lines = ReadTextLines(path);
  if (lines.empty()) throw InputError(path + ": empty stats file");
  const std::vector<std::string> header = Split(lines[0].text, ',');
  std::vector<size_t> index;
  for (const std::string& name : wanted) {
    const auto column = std::find(header.begin(), header.end(), name);
    if (header.empty() || header[0] != "timestamp_ns" || column == header.end()) {
      ThrowAtLine(path, 1, "not a visloc stats file (no timestamp_ns / " + name + " column)");
    }
    index.push_back(static_cast<size_t>(column - header.begin()));
  }
  StatsTable table;
  for (size_t i = 1; i < lines.size(); ++i) {
    const std::vector<std::string> fields = Split(lines[i].text, ',');
    const auto timestamp = fields.empty() ? std::nullopt : ParseInt64(fields[0]);
    if (!timestamp) ThrowAtLine(path, lines[i].number, "bad timestamp");
    table.timestamps.push_back(*timestamp);
    const bool posed =
        fields.size() > 2 && (fields[2] == "tracking" || fields[2] == "relocalization");
    for (size_t c = 0; c < wanted.size(); ++c) {
      const auto value = fields.size() > index[c] ? ParseDouble(fields[index[c]]) : std::nullopt;
      if (!value) ThrowAtLine(path, lines[i].number, "bad " + wanted[c]);
      const bool timing = EndsWith(wanted[c], "_ms");
      table.columns[wanted[c]].push_back(
          timing || posed ? *value : std::numeric_limits<double>::quiet_NaN());
    }
  }
  return table;
}

// A numeric CSV for --curves: a header of names, the first column x, each further column one
// curve against it.
std::vector<Curve> ReadCurves(const std::string& path, std::string* x_label) {
  const std::vector<TextLine> lines = ReadTextLines(path);
  if (lines.size() < 2) throw InputError(path + ": a curves CSV needs a header and a row");
  const std::vector<std::string> header = Split(lines[0].text, ',');
  if (header.size() < 2) ThrowAtLine(path, lines[0].number, "want x and at least one y column");
  *x_label = header[0];
  std::vector<Curve> curves(header.size() - 1);
  for (size_t c = 1; c < header.size(); ++c) curves[c - 1].title = header[c];
  for (size_t i = 1; i < lines.size(); ++i) {
    const std::vector<std::string> fields = Split(lines[i].text, ',');
    if (fields.size() != header.size()) {
      ThrowAtLine(path, lines[i].number, StrCat("want ", header.size(), " columns"));
    }
    std::vector<double> values;
    for (const std::string& field : fields) {
      const std::optional<double> value = ParseDouble(field);
      if (!value) ThrowAtLine(path, lines[i].number, "not a number: '" + field + "'");
      values.push_back(*value);
    }
    for (size_t c = 1; c < values.size(); ++c) {
      curves[c - 1].x.push_back(values[0]);
      curves[c - 1].y.push_back(values[c]);
    }
  }
  return curves;
}

}  // namespace

int RunPlot(const Args& args) {
  std::string map_path, trajectory_path, stats_path, gt_path, out;
  std::string curves_path;
  bool series = false, log_x = false;
  ArgParser parser("visloc plot",
                   "Draws a top view of a map with an estimated trajectory coloured by inlier "
                   "ratio (and ground truth beside it), or with --series the per-frame time, "
                   "inlier ratio and RANSAC iterations along the sequence from --stats; PNG or "
                   "SVG by the output's extension.");
  parser.AddFlag("map", &map_path, "map file (.db); top view");
  parser.AddFlag("trajectory", &trajectory_path, "estimated poses (TUM); top view");
  parser.AddSwitch("series", &series, "plot --stats along the sequence instead");
  parser.AddFlag("curves", &curves_path,
                 "plot curves instead: a CSV whose first column is x, each other column a curve");
  parser.AddSwitch("log-x", &log_x, "with --curves: logarithmic x axis");
  parser.AddFlag("stats", &stats_path, "per-frame statistics (CSV) for the colours");
  parser.AddFlag("gt", &gt_path, "ground truth (TUM, map frame)");
  parser.AddFlag("out", &out, "PLOT.png or PLOT.svg", true);
  bool json = false;
  parser.AddSwitch("json", &json, "print one JSON object");
  if (!parser.Parse(args, std::cout)) return 0;
  if (!curves_path.empty()) {
    std::string x_label;
    const std::vector<Curve> curves = ReadCurves(curves_path, &x_label);
    WriteCurvePlot(curves,
                   CurveAxes{std::filesystem::path(curves_path).filename().string(),
                             x_label + (log_x ? " (log scale)" : ""), log_x},
                   out);
    return PrintOutcome(
        json, StrCat("wrote ", out, ": ", curves.size(), " curves of ", curves[0].x.size(), " points"),
        {{"out", out},
         {"curves", static_cast<int64_t>(curves.size())},
         {"points", static_cast<int64_t>(curves[0].x.size())}});
  }
  if (series) {
    if (stats_path.empty()) throw UsageError("--series needs --stats");
    const StatsTable table =
        ReadStats(stats_path, {"total_ms", "inlier_ratio", "ransac_iterations"});
    WriteSeriesPlot({{"time per frame (ms)", table.columns.at("total_ms")},
                     {"inlier ratio", table.columns.at("inlier_ratio")},
                     {"RANSAC iterations", table.columns.at("ransac_iterations")}},
                    std::filesystem::path(stats_path).filename().string(), out);
    return PrintOutcome(json, StrCat("wrote ", out, ": ", table.timestamps.size(), " frames"),
                        {{"out", out}, {"frames", static_cast<int64_t>(table.timestamps.size())}});
  }
  if (map_path.empty() || trajectory_path.empty()) {
    throw UsageError("a top view needs --map and --trajectory (or use --series --stats)");
  }
  const LocalizationMap map(mapstore::LoadMap(map_path));
  PlotInput input;
  input.map = &map;
  input.estimate = ReadTum(trajectory_path);
  if (!stats_path.empty()) {
    const StatsTable table = ReadStats(stats_path, {"inlier_ratio"});
    const std::vector<double>& ratios = table.columns.at("inlier_ratio");
    for (size_t i = 0; i < ratios.size(); ++i) {
      if (std::isfinite(ratios[i])) input.inlier_ratio[table.timestamps[i]] = ratios[i];
    }
  }
  if (!gt_path.empty()) input.ground_truth = ReadTum(gt_path);
  input.title = std::filesystem::path(map_path).filename().string() + "  /  " +
                std::filesystem::path(trajectory_path).filename().string();
  const PlotStats stats = WriteTopViewPlot(input, out);
  return PrintOutcome(json,
                      StrCat("wrote ", out, ": ", stats.points_drawn, " map points, ",
                             stats.keyframes_drawn, " keyframes, ", stats.estimate_segments,
                             " trajectory segments, ", stats.gaps, " gaps"),
                      {{"out", out},
                       {"points", static_cast<int64_t>(stats.points_drawn)},
                       {"keyframes", static_cast<int64_t>(stats.keyframes_drawn)},
                       {"segments", static_cast<int64_t>(stats.estimate_segments)},
                       {"gaps", static_cast<int64_t>(stats.gaps)}});
}

}  // namespace visloc::cli
