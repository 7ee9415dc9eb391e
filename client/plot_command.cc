// `visloc plot --map MAP.db --trajectory EST.tum [--stats S.csv] [--gt GT.tum] --out P.png|P.svg`

#include <cstdio>
#include <filesystem>
#include <iostream>

#include "client/commands.h"
#include "client/plot.h"
#include "core/util/args.h"
#include "core/util/check.h"
#include "core/util/strings.h"
#include "core/util/text_file.h"
#include "dataset/tum.h"
#include "mapstore/map_store.h"

namespace visloc::cli {
namespace {

// timestamp_ns -> inlier_ratio from a stats CSV written by localize or stream.
std::map<int64_t, double> ReadInlierRatios(const std::string& path) {
  const std::vector<TextLine> lines = ReadTextLines(path);
  if (lines.empty()) throw InputError(path + ": empty stats file");
  const std::vector<std::string> header = Split(lines[0].text, ',');
  const auto column = std::find(header.begin(), header.end(), "inlier_ratio");
  if (header.empty() || header[0] != "timestamp_ns" || column == header.end()) {
    ThrowAtLine(path, 1, "not a visloc stats file (no timestamp_ns / inlier_ratio columns)");
  }
  const size_t ratio_column = static_cast<size_t>(column - header.begin());
  std::map<int64_t, double> ratios;
  for (size_t i = 1; i < lines.size(); ++i) {
    const std::vector<std::string> fields = Split(lines[i].text, ',');
    const auto timestamp = fields.empty() ? std::nullopt : ParseInt64(fields[0]);
    const auto ratio =
        fields.size() > ratio_column ? ParseDouble(fields[ratio_column]) : std::nullopt;
    if (!timestamp || !ratio) ThrowAtLine(path, lines[i].number, "bad timestamp or inlier ratio");
    ratios[*timestamp] = *ratio;
  }
  return ratios;
}

}  // namespace

int RunPlot(const Args& args) {
  std::string map_path, trajectory_path, stats_path, gt_path, out;
  ArgParser parser("visloc plot",
                   "Draws a top view of a map with an estimated trajectory coloured by inlier "
                   "ratio (and ground truth beside it), as PNG or SVG by the output's extension.");
  parser.AddFlag("map", &map_path, "map file (.db)", /*required=*/true);
  parser.AddFlag("trajectory", &trajectory_path, "estimated poses (TUM)", true);
  parser.AddFlag("stats", &stats_path, "per-frame statistics (CSV) for the colours");
  parser.AddFlag("gt", &gt_path, "ground truth (TUM, map frame)");
  parser.AddFlag("out", &out, "PLOT.png or PLOT.svg", true);
  if (!parser.Parse(args, std::cout)) return 0;
  const LocalizationMap map(mapstore::LoadMap(map_path));
  PlotInput input;
  input.map = &map;
  input.estimate = ReadTum(trajectory_path);
  if (!stats_path.empty()) input.inlier_ratio = ReadInlierRatios(stats_path);
  if (!gt_path.empty()) input.ground_truth = ReadTum(gt_path);
  input.title = std::filesystem::path(map_path).filename().string() + "  /  " +
                std::filesystem::path(trajectory_path).filename().string();
  const PlotStats stats = WriteTopViewPlot(input, out);
  std::printf("wrote %s: %d map points, %d keyframes, %d trajectory segments, %d gaps\n",
              out.c_str(), stats.points_drawn, stats.keyframes_drawn, stats.estimate_segments,
              stats.gaps);
  return 0;
}

}  // namespace visloc::cli
