#include "mapping/dataset_mapping.h"

#include "core/util/check.h"
#include "core/util/timer.h"

namespace visloc::mapping {

Map BuildMap(const Dataset& dataset, const MapBuilderOptions& options, const MapMetadata& metadata,
             MapBuildStats* stats, Trajectory* frame_trajectory,
             const std::function<void(int, int, const std::string&)>& progress) {
  if (!dataset.has_stereo())
    throw InputError(StrCat(dataset.root, ": map building needs a stereo dataset (no cam1)"));
  Timer timer;
  MapBuilder builder(dataset.left.camera, dataset.right->camera, dataset.right_from_left(),
                     options);
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
  if (stats) {
    *stats = builder.stats();
    stats->total_ms = timer.ElapsedMs();
  }
  if (frame_trajectory) *frame_trajectory = builder.FrameTrajectory();
  return map;
}

}  // namespace visloc::mapping
