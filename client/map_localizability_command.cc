// `visloc map localizability`: where in a map's site a robot will localize well, looking which
// way, predicted from the map alone (core/localization/localizability.h), written as a picture
// and as data.

#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <memory>

#include "client/commands.h"
#include "client/localizability_plot.h"
#include "client/map_report.h"
#include "client/remote_map.h"
#include "core/localization/localizability.h"
#include "core/util/args.h"
#include "core/util/check.h"
#include "core/util/json.h"
#include "core/util/strings.h"
#include "dataset/tum.h"
#include "mapping/site_alignment.h"
#include "mapstore/map_store.h"

namespace visloc::cli {
namespace {

std::string Number(double value) {
  return std::isfinite(value) ? FormatFixed(value, 4) : std::string("inf");
}

void WriteGridCsv(const LocalizabilityGrid& grid, const std::string& path) {
  std::ofstream out(path);
  if (!out) throw InputError(path + ": cannot write");
  out << "x_m,y_m,heading_deg,expected_inliers,position_sigma_m,point_variance_ratio,visible_"
         "points,good\n";
  for (int iy = 0; iy < grid.cells_y; ++iy) {
    for (int ix = 0; ix < grid.cells_x; ++ix) {
      const Eigen::Vector2d c = grid.CellCenter(ix, iy);
      for (int h = 0; h < grid.headings; ++h) {
        const LocalizabilityEstimate& e = grid.at(ix, iy, h);
        out << FormatFixed(c.x(), 3) << "," << FormatFixed(c.y(), 3) << ","
            << FormatFixed(grid.heading_deg(h), 1) << "," << FormatFixed(e.expected_inliers, 1)
            << "," << Number(e.position_sigma_m) << "," << FormatFixed(e.point_variance_ratio, 3)
            << "," << FormatFixed(e.visible_points, 1) << "," << (e.good ? 1 : 0) << "\n";
      }
    }
  }
  if (!out.flush()) throw InputError(path + ": cannot write");
}

// Each pose of a trajectory (map frame): predicted at the pose itself and read from the grid at
// its cell and nearest heading.
void WritePathCsv(const Trajectory& path_in_map, const LocalizabilityGrid& grid,
                  const LocalizabilityPredictor& predictor, const std::string& path) {
  std::ofstream out(path);
  if (!out) throw InputError(path + ": cannot write");
  out << "timestamp_ns,expected_inliers,position_sigma_m,point_variance_ratio,good,cell_x_m,"
         "cell_y_m,"
         "cell_heading_deg,cell_expected_inliers,cell_position_sigma_m,cell_good\n";
  for (const StampedPose& pose : path_in_map) {
    const LocalizabilityEstimate e = predictor.Predict(pose.pose);
    out << pose.timestamp_ns << "," << FormatFixed(e.expected_inliers, 1) << ","
        << Number(e.position_sigma_m) << "," << FormatFixed(e.point_variance_ratio, 3) << ","
        << (e.good ? 1 : 0);
    int ix = 0, iy = 0, h = 0;
    if (grid.Locate(grid.site_from_map * pose.pose, &ix, &iy, &h)) {
      const LocalizabilityEstimate& cell = grid.at(ix, iy, h);
      const Eigen::Vector2d c = grid.CellCenter(ix, iy);
      out << "," << FormatFixed(c.x(), 3) << "," << FormatFixed(c.y(), 3) << ","
          << FormatFixed(grid.heading_deg(h), 1) << "," << FormatFixed(cell.expected_inliers, 1)
          << "," << Number(cell.position_sigma_m) << "," << (cell.good ? 1 : 0);
    } else {
      out << ",,,,0,inf,0";  // Outside the grid: nothing mapped there.
    }
    out << "\n";
  }
  if (!out.flush()) throw InputError(path + ": cannot write");
}

std::string SummaryJson(const std::string& map_path, const std::string& prefix,
                        const LocalizabilityReport& report, const LocalizabilityOptions& options,
                        int path_poses) {
  const LocalizabilityGrid& grid = report.grid;
  const LocalizabilityStats& stats = report.stats;
  JsonWriter out;
  out.BeginObject()
      .Field("map", map_path)
      .Field("frame", report.frame)
      .Field("frame_how", report.frame_how);
  WritePoseField(out, "site_from_map", grid.site_from_map);
  out.Field("min_x_m", grid.min_x_m)
      .Field("min_y_m", grid.min_y_m)
      .Field("cell_m", grid.cell_m)
      .Field("cells_x", grid.cells_x)
      .Field("cells_y", grid.cells_y)
      .Field("headings", grid.headings)
      .Field("height_m", grid.height_m)
      .Field("pitch_deg", grid.pitch_deg)
      .Field("good_inliers", options.good_inliers)
      .Field("good_sigma_m", options.good_sigma_m)
      .Field("poses", stats.poses)
      .Field("good_poses", stats.good_poses)
      .Field("keyframes", stats.keyframes)
      .Field("seconds", stats.seconds)
      .Field("csv", prefix + ".csv")
      .Field("png", prefix + ".png");
  if (path_poses > 0) out.Field("path_csv", prefix + ".path.csv").Field("path_poses", path_poses);
  out.EndObject();
  return out.str();
}

}  // namespace

int RunMapLocalizability(const Args& args) {
  std::string map_path, prefix, path_tum;
  LocalizabilityOptions options;
  double height_m = NAN, pitch_deg = NAN;
  bool json = false;
  ArgParser parser(
      "visloc map localizability",
      "Where in the map's site a robot will localize well, looking which way, from the map "
      "alone: for each cell of a grid over the mapped area and each heading, the inliers a "
      "camera there can expect (points in view by the learned visibility kernel and the "
      "frustum, times their matchable share) and the position sigma their Fisher information "
      "gives. Writes PREFIX.png (a heat map under the map's points and the keyframes' path), "
      "PREFIX.csv (one row per cell and heading, site frame) and PREFIX.json. With --server, "
      "the server's grid of a map it holds (no map points in the picture, no --at).");
  parser.AddPositional("MAP", &map_path, "the map file, or with --server the map's name there");
  parser.AddFlag("out", &prefix, "output prefix: PREFIX.png, PREFIX.csv, PREFIX.json",
                 /*required=*/true);
  parser.AddFlag("cell", &options.cell_m, "grid cell side, metres");
  parser.AddFlag("headings", &options.headings, "headings per cell, evenly from the site's +x");
  parser.AddFlag("height", &height_m, "the camera's height, metres, as z in the site frame");
  parser.AddFlag("pitch", &pitch_deg, "the camera's pitch below level, degrees");
  parser.SetDefaultText("height", "the keyframes' median");
  parser.SetDefaultText("pitch", "the keyframes' median");
  parser.AddFlag("margin", &options.margin_m, "metres the grid reaches beyond the keyframes");
  parser.AddFlag("at", &path_tum,
                 "TUM: poses in the map frame (a planned path, a run's ground truth) predicted "
                 "one by one, written to PREFIX.path.csv");
  parser.AddFlag("threads", &options.threads, "threads (0: every core)");
  Connection server;
  server.AddFlags(parser, /*server_required=*/false);
  parser.AddSwitch("json", &json, "print one JSON object");
  if (!parser.Parse(args, std::cout)) return 0;
  if (map_path.empty()) throw UsageError("missing MAP");
  if (!(options.cell_m > 0)) throw UsageError("--cell must be positive");
  if (options.headings < 1 || options.headings > 72) throw UsageError("--headings: 1 to 72");
  if (!(options.margin_m >= 0)) throw UsageError("--margin must not be negative");
  if (!std::isnan(height_m)) options.height_m = height_m;
  if (!std::isnan(pitch_deg)) {
    if (!(std::abs(pitch_deg) < 90)) throw UsageError("--pitch must be within (-90, 90) degrees");
    options.pitch_deg = pitch_deg;
  }
  server.ApplyEnvironment();
  if (!server.server.empty() && !path_tum.empty()) {
    throw UsageError("--at predicts poses with the map file: run it without --server");
  }
  const Trajectory path_in_map = path_tum.empty() ? Trajectory{} : ReadTum(path_tum);

  LocalizabilityReport report;
  std::unique_ptr<LocalizationMap> map;  // None for a server's map: its grid comes over the wire.
  if (!server.server.empty()) {
    report = RemoteLocalizability(server, map_path, options);
  } else {
    map = std::make_unique<LocalizationMap>(mapstore::LoadMap(map_path));
    std::string why_not;
    const std::optional<mapping::PlanFrame> frame = mapping::PlanFrameOf(map->map(), &why_not);
    if (!frame) throw InputError(why_not + ": a localizability grid needs a level frame");
    report.map = map->map().metadata.name;
    report.frame = frame->name;
    report.frame_how = frame->how;
    report.grid = ComputeLocalizability(*map, frame->site_from_map, options, &report.stats);
  }
  const LocalizabilityGrid& grid = report.grid;
  const LocalizabilityStats& stats = report.stats;
  WriteGridCsv(grid, prefix + ".csv");
  WriteLocalizabilityPng(
      {&grid, map.get(), options.good_inliers,
       StrCat(report.map, ": localizability, ", report.frame_how, "; camera at z ",
              FormatFixed(grid.height_m, 2), " m, pitch ", FormatFixed(grid.pitch_deg, 1), " deg")},
      prefix + ".png");
  if (!path_in_map.empty()) {
    WritePathCsv(path_in_map, grid, LocalizabilityPredictor(*map, options), prefix + ".path.csv");
  }
  const std::string summary =
      SummaryJson(map_path, prefix, report, options, static_cast<int>(path_in_map.size()));
  {
    std::ofstream out(prefix + ".json");
    out << summary << "\n";
    if (!out.flush()) throw InputError(prefix + ".json: cannot write");
  }
  if (json) {
    std::cout << summary << "\n";
  } else {
    std::printf("%s: %d x %d cells of %.2f m, %d headings, in the %s frame (%s)\n",
                map_path.c_str(), grid.cells_x, grid.cells_y, grid.cell_m, grid.headings,
                report.frame.c_str(), report.frame_how.c_str());
    std::printf(
        "camera at z %.2f m, pitched %.1f deg down; %d of %d poses good (>= %.0f inliers, "
        "sigma <= %.0f cm); %.2f s over %d keyframes\n",
        grid.height_m, grid.pitch_deg, stats.good_poses, stats.poses, options.good_inliers,
        100 * options.good_sigma_m, stats.seconds, stats.keyframes);
    std::printf("wrote %s.png, %s.csv, %s.json%s\n", prefix.c_str(), prefix.c_str(), prefix.c_str(),
                path_in_map.empty() ? "" : StrCat(", ", prefix, ".path.csv").c_str());
  }
  return 0;
}

}  // namespace visloc::cli
