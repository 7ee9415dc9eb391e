#include "mapping/stereo_source.h"

#include <future>

#include "core/util/parallel.h"
#include "core/util/timer.h"

namespace visloc::mapping {

Map StereoSource::BuildMap(const MapBuilderOptions& options, const MapMetadata& metadata,
                           MapBuildStats* stats, Trajectory* frame_trajectory,
                           const MappingProgress& progress) const {
  return MapStereoFrames(*this, options, metadata, stats, frame_trajectory, progress);
}

Map MapStereoFrames(const StereoSource& source, const MapBuilderOptions& options,
                    const MapMetadata& metadata, MapBuildStats* stats, Trajectory* frame_trajectory,
                    const StereoSource::MappingProgress& progress) {
  Timer timer;
  MapBuilder builder(source.left_camera(), source.right_camera(), source.right_from_left(),
                     options);
  const int total = source.size();
  const bool prefetch = ResolveThreads(options.threads) > 1;
  std::future<StereoImages> next;
  if (prefetch && total > 0) next = std::async(std::launch::async, [&] { return source.Read(0); });
  for (int i = 0; i < total; ++i) {
    const StereoImages frame = prefetch ? next.get() : source.Read(i);
    if (prefetch && i + 1 < total) {
      next = std::async(std::launch::async, [&source, i] { return source.Read(i + 1); });
    }
    builder.AddFrame(frame.timestamp_ns, frame.left_raw, frame.right_raw);
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
