#include "mapping/dataset_mapping.h"

#include <algorithm>
#include <filesystem>

#include "core/util/check.h"
#include "core/util/strings.h"
#include "core/util/timer.h"

namespace visloc::mapping {

void DatasetMappingOptions::Check() const {
  builder.Check();
  VISLOC_CHECK(check_frames >= 0 && min_points >= 0, "check_frames ", check_frames, ", min_points ",
               min_points);
}

namespace {

void RequireStereo(const Dataset& dataset) {
  if (!dataset.has_stereo())
    throw InputError(StrCat(dataset.root, ": map building needs a stereo dataset (no cam1)"));
}

DatasetCheck CheckRig(const Dataset& dataset, const DatasetMappingOptions& options, int frames) {
  DatasetCheckOptions check;
  check.sample_frames = frames;
  check.features = options.builder.features;
  check.scale_feature_count = options.builder.scale_feature_count;
  check.stereo = options.builder.stereo;
  return CheckDataset(dataset, check);
}

}  // namespace

DatasetSource::DatasetSource(const Dataset& dataset, std::string name)
    : dataset_(dataset), name_(name.empty() ? dataset.root : std::move(name)) {
  RequireStereo(dataset);
}

std::string DatasetSource::origin() const {
  return std::filesystem::absolute(dataset_.root).string();
}

StereoImages DatasetSource::Read(int index) const {
  const FrameRecord& frame = dataset_.frames[index];
  const Camera& right = dataset_.right->camera;
  return {frame.timestamp_ns, ReadLeft(index),
          LoadGreyImage(frame.right_path, right.width(), right.height())};
}

cv::Mat DatasetSource::ReadLeft(int index) const {
  const Camera& left = dataset_.left.camera;
  return LoadGreyImage(dataset_.frames[index].left_path, left.width(), left.height());
}

Map DatasetSource::BuildMap(const MapBuilderOptions& options, const MapMetadata& metadata,
                            MapBuildStats* stats, Trajectory* frame_trajectory,
                            const MappingProgress& progress) const {
  DatasetMappingOptions dataset_options;
  dataset_options.builder = options;
  return mapping::BuildMap(dataset_, dataset_options, metadata, stats, frame_trajectory, progress);
}

Map BuildMap(const Dataset& dataset, const DatasetMappingOptions& options,
             const MapMetadata& metadata, MapBuildStats* stats, Trajectory* frame_trajectory,
             const std::function<void(int, int, const std::string&)>& progress) {
  options.Check();
  RequireStereo(dataset);
  Timer timer;
  if (options.check_frames > 0) {
    const DatasetCheck check = CheckRig(dataset, options, options.check_frames);
    if (!check.ok()) {
      throw InputError(StrCat("this rig would not map: ", check.problems.front(),
                              " ('visloc dataset check' gives the full report)"));
    }
  }
  Map map = MapStereoFrames(DatasetSource(dataset), options.builder, metadata, stats,
                            frame_trajectory, progress);
  if (static_cast<int>(map.points.size()) < options.min_points) {
    const DatasetCheck check = CheckRig(dataset, options, std::max(3, options.check_frames));
    throw InputError(
        StrCat("the map would have ", map.points.size(), " points, fewer than ", options.min_points,
               " (--min-points): ",
               check.ok() ? StrCat("stereo: ", StereoEvidence(check)) : check.problems.front()));
  }
  // The whole build, the rig check included.
  if (stats) stats->total_ms = timer.ElapsedMs();
  return map;
}

}  // namespace visloc::mapping
