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

// The map's up direction from the best the recording offers; what told it, or why nothing did,
// in `report`.
std::optional<MapGravity> FindGravity(const Dataset& dataset, const DatasetMappingOptions& options,
                                      const Trajectory& map_from_cam, const Map& map,
                                      std::string* report) {
  std::vector<std::string> reasons;
  if (!dataset.imu.empty()) {
    std::vector<ImuReading> samples;
    samples.reserve(dataset.imu.size());
    for (const ImuSample& s : dataset.imu) {
      samples.push_back({s.timestamp_ns, s.accel_mps2, s.gyro_radps});
    }
    const GravityResult imu =
        GravityFromImu(map_from_cam, samples, dataset.left.body_from_cam, options.gravity);
    if (imu.gravity) {
      *report =
          StrCat("from the accelerometer (", FormatFixed(imu.measured_gravity_mps2, 3), " m/s^2)");
      // The floor, where one is seen, tells the tilts the run left loose (its bias's).
      const GravityResult floor = GravityFromFloor(map, options.gravity);
      if (!floor.gravity || floor.gravity->source != MapGravity::Source::kFloor) {
        return imu.gravity;
      }
      const GravityResult combined = CombineImuAndFloor(imu, floor, options.gravity);
      if (!combined.gravity) {
        *report += " (not combined with the floor: " + combined.why_not + ")";
        return imu.gravity;
      }
      *report += StrCat(" and the floor (", FormatFixed(imu.gravity->sigma_deg, 2), " and ",
                        FormatFixed(floor.gravity->sigma_deg, 2), " deg alone)");
      return combined.gravity;
    }
    reasons.push_back(imu.why_not);
  }
  if (options.level_body) {
    *report = "from the rig's body, declared level";
    return GravityFromLevelBody(map, dataset.left.body_from_cam, options.gravity);
  }
  const GravityResult floor = GravityFromFloor(map, options.gravity);
  if (floor.gravity) {
    *report = floor.gravity->source == MapGravity::Source::kFloor
                  ? "from the floor"
                  : "from the keyframes' motion plane";
    if (!reasons.empty()) *report += " (the accelerometer: " + reasons.front() + ")";
    return floor.gravity;
  }
  reasons.push_back(floor.why_not);
  *report = "not found:";
  for (size_t i = 0; i < reasons.size(); ++i) *report += (i ? "; " : " ") + reasons[i];
  return std::nullopt;
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
  Trajectory map_from_cam;
  Map map = MapStereoFrames(DatasetSource(dataset), options.builder, metadata, stats, &map_from_cam,
                            progress);
  std::string gravity_report;
  map.metadata.gravity = FindGravity(dataset, options, map_from_cam, map, &gravity_report);
  if (stats) stats->gravity = gravity_report;
  if (frame_trajectory) *frame_trajectory = std::move(map_from_cam);
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
