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
  // With threads, frame i + 1 is read and its features found (MapBuilder::Prepare) while frame
  // i is tracked and adjusted, which is mostly one thread's work: on two cores the generated
  // building's first 4,000 frames mapped 1.17 and 1.23 times as fast (two runs), to the same map.
  const bool prefetch = ResolveThreads(options.threads) > 1;
  struct Prepared {
    int64_t timestamp_ns;
    StereoFrameSearch frame;
  };
  const auto prepare = [&source, &builder](int i) {
    const StereoImages images = source.Read(i);
    return Prepared{images.timestamp_ns, builder.Prepare(images.left_raw, images.right_raw)};
  };
  std::future<Prepared> next;
  if (prefetch && total > 0) next = std::async(std::launch::async, prepare, 0);
  for (int i = 0; i < total; ++i) {
    Prepared frame = prefetch ? next.get() : prepare(i);
    if (prefetch && i + 1 < total) next = std::async(std::launch::async, prepare, i + 1);
    builder.AddPrepared(frame.timestamp_ns, std::move(frame.frame));
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
