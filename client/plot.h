#pragma once
// `visloc plot`: a top view of a map and a trajectory, like the paper's Figs. 17 and 19: map
// points (grey), keyframes (blue), ground truth (wide violet), and the estimated trajectory
// coloured by inlier ratio (red 0 -> yellow -> green 1). Where the estimate has a gap (lost frames)
// the two ends are joined by a dashed line, so a kidnapping shows as a jump. PNG or SVG by the
// output's extension.
//
// "Top" is the map's site frame's z (up: the frame map align tied it to, else its level frame),
// x to the right and y up the picture as on the operator's page; for a map that records no up,
// the normal of the plane the keyframes lie in (a ground robot's head), or the map's -y axis (up
// for the first camera) when they do not span a plane.

#include <map>
#include <string>
#include <vector>

#include "core/geometry/trajectory.h"
#include "core/map/localization_map.h"

namespace visloc::cli {

struct PlotInput {
  const LocalizationMap* map = nullptr;
  Trajectory estimate;                     // map_from_cam
  std::map<int64_t, double> inlier_ratio;  // By timestamp; missing: drawn grey.
  Trajectory ground_truth;                 // Optional.
  std::string title;
};

struct PlotStats {
  int points_drawn = 0;
  int keyframes_drawn = 0;
  int estimate_segments = 0;
  int gaps = 0;  // Dashed jumps across lost stretches.
};

// Writes PNG or SVG to `path` (by extension). Throws InputError for another extension.
PlotStats WriteTopViewPlot(const PlotInput& input, const std::string& path);

// Per-frame series along a sequence, one panel each, stacked (the paper's Figs. 10 and 22):
// e.g. {"total time (ms)", times}, {"inlier ratio", ratios}, {"RANSAC iterations", its}.
// Frames without a value are NaN and leave a gap. PNG or SVG by extension.
struct Series {
  std::string title;
  std::vector<double> values;
};
void WriteSeriesPlot(const std::vector<Series>& panels, const std::string& title,
                     const std::string& path);

// Curves y(x), one panel each, stacked, sharing an x axis (the scaling curves: relocalization
// time against keyframes, load time against points). With log_x the x axis is logarithmic
// (x <= 0 is left out). Up to 50 points get markers with their values.
struct Curve {
  std::string title;
  std::vector<double> x, y;
};
struct CurveAxes {
  std::string title;
  std::string x_label;
  bool log_x = false;
};
void WriteCurvePlot(const std::vector<Curve>& panels, const CurveAxes& axes,
                    const std::string& path);

}  // namespace visloc::cli
