#pragma once
// `visloc dataset check`: before a build, whether a stereo dataset will map, and if not, why.
// The cameras and their rectified pair, the epipolar residual and the mapper's stereo matches
// on frames spread over the sequence (mapping/stereo_check.h), the stereo points' depth range,
// and the timestamps (gaps, left/right pairing).

#include <functional>
#include <string>
#include <vector>

#include "dataset/dataset.h"
#include "mapping/stereo_check.h"

namespace visloc::mapping {

struct DatasetCheckOptions {
  int sample_frames = 8;  // Frames examined, spread evenly over the sequence.
  FeatureSettings features = DefaultFeatureSettings("harris_surf16");  // As for map build:
  bool scale_feature_count = true;  // max_features at 320x240, scaled to the images.
  StereoMatchOptions stereo;
  // The rig fails the check when the median row difference of left/right descriptor matches
  // exceeds this (a sound calibration: well below 0.5 px) ...
  double max_row_difference_px = 1.0;
  // ... or the mapper's row search matches fewer keypoints than this per frame (median).
  int min_stereo_matches = 50;
  void Check() const;
};

struct SampledFrame {
  int index = 0;  // Into Dataset::frames.
  int64_t timestamp_ns = 0;
  StereoPairCheck check;
};

struct DatasetCheck {
  // The rectified pair.
  double rectified_focal_px = 0.0;
  double baseline_m = 0.0;
  double rectification_deg = 0.0;  // Rotation of the left camera into the rectified frame.
  // Timing.
  int frames = 0;
  double duration_s = 0.0;
  double median_period_s = 0.0;
  double max_gap_s = 0.0;
  int long_gaps = 0;  // Gaps over 1.5 median periods.
  StereoPairing pairing;
  // Sampled frames, and their measurements pooled.
  std::vector<SampledFrame> samples;
  int descriptor_matches = 0;
  double row_difference_median_px = 0.0;
  double row_difference_p95_px = 0.0;
  double disparity_median_px = 0.0;
  double stereo_matches_median = 0.0;
  double keypoints_median = 0.0;
  double depth_p5_m = 0.0, depth_median_m = 0.0, depth_p95_m = 0.0;
  std::vector<std::string> problems;  // Why the rig would not map; empty when it would.
  std::vector<std::string> warnings;  // Worth knowing, but it maps.
  bool ok() const { return problems.empty(); }
};

// Throws InputError for a dataset without frames or unreadable images.
DatasetCheck CheckDataset(const Dataset& dataset, const DatasetCheckOptions& options,
                          const std::function<void(int, int)>& progress = nullptr);

// One line with the stereo evidence, e.g. for a build that found too few points.
std::string StereoEvidence(const DatasetCheck& check);

}  // namespace visloc::mapping
