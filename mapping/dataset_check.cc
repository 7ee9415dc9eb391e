#include "mapping/dataset_check.h"

#include <algorithm>
#include <cmath>

#include "core/util/check.h"
#include "core/util/strings.h"

namespace visloc::mapping {

void DatasetCheckOptions::Check() const {
  stereo.Check();
  VISLOC_CHECK(sample_frames >= 1 && max_row_difference_px > 0 && min_stereo_matches >= 0,
               "dataset check options: ", sample_frames, " frames, ", max_row_difference_px,
               " px, ", min_stereo_matches, " matches");
}

namespace {

void CheckTiming(const Dataset& dataset, DatasetCheck* check) {
  const auto& frames = dataset.frames;
  check->frames = static_cast<int>(frames.size());
  check->pairing = dataset.pairing;
  if (frames.size() < 2) return;
  check->duration_s = (frames.back().timestamp_ns - frames.front().timestamp_ns) * 1e-9;
  std::vector<double> periods;
  for (size_t i = 1; i < frames.size(); ++i) {
    periods.push_back((frames[i].timestamp_ns - frames[i - 1].timestamp_ns) * 1e-9);
  }
  check->median_period_s = Quantile(periods, 0.5);
  check->max_gap_s = *std::max_element(periods.begin(), periods.end());
  check->long_gaps = static_cast<int>(std::count_if(
      periods.begin(), periods.end(), [&](double p) { return p > 1.5 * check->median_period_s; }));
}

// Pools the sampled frames' measurements and judges them.
void Summarize(const DatasetCheckOptions& options, DatasetCheck* check) {
  std::vector<double> rows, disparities, depths, matches, keypoints;
  for (const SampledFrame& s : check->samples) {
    rows.insert(rows.end(), s.check.row_difference_px.begin(), s.check.row_difference_px.end());
    disparities.insert(disparities.end(), s.check.disparity_px.begin(),
                       s.check.disparity_px.end());
    depths.insert(depths.end(), s.check.depth_m.begin(), s.check.depth_m.end());
    matches.push_back(s.check.stereo.matched);
    keypoints.push_back(s.check.left_keypoints);
  }
  check->descriptor_matches = static_cast<int>(rows.size());
  check->row_difference_median_px = Quantile(rows, 0.5);
  check->row_difference_p95_px = Quantile(rows, 0.95);
  check->disparity_median_px = Quantile(disparities, 0.5);
  check->stereo_matches_median = Quantile(matches, 0.5);
  check->keypoints_median = Quantile(keypoints, 0.5);
  check->depth_p5_m = Quantile(depths, 0.05);
  check->depth_median_m = Quantile(depths, 0.5);
  check->depth_p95_m = Quantile(depths, 0.95);

  const int samples = static_cast<int>(check->samples.size());
  if (check->descriptor_matches < 5 * samples) {
    check->problems.push_back(StrCat(
        "the left and right images share almost no features (", check->descriptor_matches,
        " descriptor matches in ", samples, " frames): are cam0 and cam1 one rig, in sync?"));
  } else {
    if (check->row_difference_median_px > options.max_row_difference_px) {
      check->problems.push_back(StrCat(
          "left/right matches are ", FormatFixed(check->row_difference_median_px, 1),
          " px apart in row after rectification (median; a calibrated rig: under 0.5 px): "
          "check cam1's T_BS and both cameras' intrinsics and distortion"));
    }
    if (check->disparity_median_px < 0) {
      check->problems.push_back(StrCat("the median disparity is ",
                                       FormatFixed(check->disparity_median_px, 1),
                                       " px (points appear right of their left-image position "
                                       "in the right image): are cam0 and cam1 swapped?"));
    }
  }
  if (check->stereo_matches_median < options.min_stereo_matches) {
    check->problems.push_back(StrCat("stereo: ", StereoEvidence(*check)));
  }
  if (check->pairing.unpaired_left + check->pairing.unpaired_right > 0) {
    check->warnings.push_back(StrCat(check->pairing.unpaired_left, " left and ",
                                     check->pairing.unpaired_right,
                                     " right images have no partner within 2 ms: left out"));
  }
  if (check->long_gaps > 0) {
    check->warnings.push_back(StrCat(check->long_gaps, " gaps over 1.5 frame periods (longest ",
                                     FormatFixed(check->max_gap_s * 1e3, 0), " ms): dropped frames?"));
  }
}

}  // namespace

std::string StereoEvidence(const DatasetCheck& check) {
  std::string evidence =
      StrCat(FormatFixed(check.stereo_matches_median, 0), " of ", FormatFixed(check.keypoints_median, 0),
             " left keypoints matched per frame (median)");
  if (!check.samples.empty()) {
    const StereoMatchStats& s = check.samples.front().check.stereo;
    evidence += StrCat(" [first frame: ", s.weak, " weak correlation, ", s.ambiguous,
                       " ambiguous, ", s.refine_rejected, " failed refinement, ",
                       s.keypoints - s.searched, " outside the search range]");
  }
  if (check.descriptor_matches > 0) {
    evidence += StrCat("; the median row difference of candidate matches is ",
                       FormatFixed(check.row_difference_median_px, 2), " px");
    if (check.row_difference_median_px > 1.0) evidence += " (is cam1's T_BS right?)";
  }
  return evidence;
}

DatasetCheck CheckDataset(const Dataset& dataset, const DatasetCheckOptions& options,
                          const std::function<void(int, int)>& progress) {
  options.Check();
  DatasetCheck check;
  if (dataset.frames.empty()) throw InputError(StrCat(dataset.root, ": no frames"));
  CheckTiming(dataset, &check);
  if (!dataset.has_stereo()) {
    check.problems.push_back("no right camera (cam1 / image_1): map building needs stereo");
    return check;
  }
  const Camera& left = dataset.left.camera;
  const StereoRectifier rectifier(left, dataset.right->camera, dataset.right_from_left());
  check.rectified_focal_px = rectifier.rectified_camera().fx();
  check.baseline_m = rectifier.baseline_m();
  check.rectification_deg = RotationAngleDeg(rectifier.rect_from_left());
  const auto extractor = CreateFeatureExtractor(
      options.scale_feature_count
          ? FeatureSettingsForImage(options.features, left.width(), left.height())
          : options.features);
  const int n = static_cast<int>(dataset.frames.size());
  const int samples = std::min(n, options.sample_frames);
  for (int s = 0; s < samples; ++s) {
    const int index = samples == 1 ? 0 : static_cast<int>(std::lround(s * (n - 1.0) / (samples - 1)));
    const FrameRecord& frame = dataset.frames[index];
    const cv::Mat left_image = LoadGreyImage(frame.left_path, left.width(), left.height());
    const cv::Mat right_image = LoadGreyImage(frame.right_path, left.width(), left.height());
    check.samples.push_back({index, frame.timestamp_ns,
                             CheckStereoPair(left_image, right_image, *extractor, rectifier,
                                             options.stereo)});
    if (progress) progress(s + 1, samples);
  }
  Summarize(options, &check);
  return check;
}

}  // namespace visloc::mapping
