#include "mapping/dataset_mapping.h"

#include <algorithm>

#include "core/util/check.h"
#include "core/util/strings.h"
#include "core/util/timer.h"

namespace visloc::mapping {

void DatasetMappingOptions::Check() const {
  builder.Check();
  VISLOC_CHECK(check_frames >= 0 && min_points >= 0, "check_frames ", check_frames,
               ", min_points ", min_points);
}

namespace {

DatasetCheck CheckRig(const Dataset& dataset, const DatasetMappingOptions& options, int frames) {
  DatasetCheckOptions check;
  check.sample_frames = frames;
  check.features = options.builder.features;
  check.scale_feature_count = options.builder.scale_feature_count;
  check.stereo = options.builder.stereo;
  return CheckDataset(dataset, check);
}

}  // namespace

Map BuildMap(const Dataset& dataset, const DatasetMappingOptions& options,
             const MapMetadata& metadata, MapBuildStats* stats, Trajectory* frame_trajectory,
             const std::function<void(int, int, const std::string&)>& progress) {
  options.Check();
  if (!dataset.has_stereo())
    throw InputError(StrCat(dataset.root, ": map building needs a stereo dataset (no cam1)"));
  Timer timer;
  if (options.check_frames > 0) {
    const DatasetCheck check = CheckRig(dataset, options, options.check_frames);
    if (!check.ok()) {
      throw InputError(StrCat("this rig would not map: ", check.problems.front(),
                              " ('visloc dataset check' gives the full report)"));
    }
  }
  MapBuilder builder(dataset.left.camera, dataset.right->camera, dataset.right_from_left(),
                     options.builder);
  const int total = static_cast<int>(dataset.frames.size());
  for (int i = 0; i < total; ++i) {
    const FrameRecord& frame = dataset.frames[i];
    const cv::Mat left =
        LoadGreyImage(frame.left_path, dataset.left.camera.width(), dataset.left.camera.height());
    const cv::Mat right = LoadGreyImage(frame.right_path, dataset.right->camera.width(),
                                        dataset.right->camera.height());
    builder.AddFrame(frame.timestamp_ns, left, right);
    if (progress) progress(i + 1, total, builder.Status());
  }
  if (progress) progress(total, total, "global bundle adjustment, visibility learning, vocabulary");
  Map map = builder.Finish(metadata);
  if (static_cast<int>(map.points.size()) < options.min_points) {
    const DatasetCheck check = CheckRig(dataset, options, std::max(3, options.check_frames));
    throw InputError(StrCat("the map would have ", map.points.size(), " points, fewer than ",
                            options.min_points, " (--min-points): ",
                            check.ok() ? StrCat("stereo: ", StereoEvidence(check))
                                       : check.problems.front()));
  }
  if (stats) {
    *stats = builder.stats();
    stats->total_ms = timer.ElapsedMs();
  }
  if (frame_trajectory) *frame_trajectory = builder.FrameTrajectory();
  return map;
}

}  // namespace visloc::mapping
