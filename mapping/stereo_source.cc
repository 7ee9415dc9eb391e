#include "mapping/stereo_source.h"

#include <optional>

#include "core/util/parallel.h"
#include "core/util/prefetch.h"
#include "core/util/timer.h"

namespace visloc::mapping {
namespace {

// Frames prepared ahead of the mapping thread: a stereo frame's images and search take a few
// MB (about 2 at 320x240, 12 at KITTI's 1241x376).
constexpr int kPrefetchFrames = 4;

}  // namespace

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
  // With threads, the next frames are read, their features found and their stereo matches
  // searched (MapBuilder::Prepare, StereoFrameSearch::SearchAhead) on a thread of their own while
  // frame i is tracked and adjusted, which is mostly one thread's work. A keyframe's adjustment
  // takes several frames' time: frames prepared during it are mapped quickly after it. Tracking
  // alone would search only the keypoints it matched (9 in 10 of them on the generated
  // building), but on the mapping thread.
  const bool prefetch = ResolveThreads(options.threads) > 1;
  struct Prepared {
    int64_t timestamp_ns;
    StereoFrameSearch frame;
  };
  std::optional<OrderedPrefetch<StereoImages>> read_ahead;
  if (prefetch) {
    read_ahead.emplace(total, kPrefetchFrames, [&source](int i) { return source.Read(i); });
  }
  const auto prepare = [&source, &builder, prefetch, &read_ahead](int i) {
    const StereoImages images = prefetch ? read_ahead->Next() : source.Read(i);
    Prepared prepared{images.timestamp_ns, builder.Prepare(images.left_raw, images.right_raw)};
    if (prefetch) prepared.frame.SearchAhead();
    return prepared;
  };
  std::optional<OrderedPrefetch<Prepared>> ahead;
  if (prefetch) ahead.emplace(total, kPrefetchFrames, prepare);
  for (int i = 0; i < total; ++i) {
    Prepared frame = prefetch ? ahead->Next() : prepare(i);
    builder.AddPrepared(frame.timestamp_ns, std::move(frame.frame));
    if (progress) progress(i + 1, total, builder.Status());
  }
  ahead.reset();  // Before the frames it reads from.
  read_ahead.reset();
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
