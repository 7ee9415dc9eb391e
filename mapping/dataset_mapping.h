#pragma once
// Feeds a recorded stereo sequence (dataset/) to the mapping pipelines: the dataset driver that
// `visloc map build`, `map extend`, `map update` and the tests use. The pipelines themselves take
// a StereoSource and know nothing of datasets or files.

#include <functional>
#include <string>

#include "dataset/dataset.h"
#include "mapping/dataset_check.h"
#include "mapping/gravity.h"
#include "mapping/map_builder.h"
#include "mapping/stereo_source.h"

namespace visloc::mapping {

struct DatasetMappingOptions {
  MapBuilderOptions builder;
  // Before the build, the rig is checked on this many frames (CheckDataset); a rig that would
  // not map is refused with the reason. 0 skips the check.
  int check_frames = 3;
  // A map with fewer points is refused, with the stereo evidence, rather than written.
  int min_points = 100;
  // Up (gravity.h): from the accelerometer when the recording has one, else from the rig's body
  // when the operator declares it level (`level_body`), else from the floor.
  bool level_body = false;
  GravityOptions gravity;
  void Check() const;
};

// A stereo dataset as a StereoSource: images decoded as they are read. Its BuildMap is the
// dataset BuildMap below with default checks (the rig first, minimum points after). `name` is
// what errors call it (by default the dataset's folder). The dataset must outlive the source.
class DatasetSource final : public StereoSource {
 public:
  // Throws InputError for a monocular dataset.
  explicit DatasetSource(const Dataset& dataset, std::string name = "");

  std::string name() const override { return name_; }
  std::string origin() const override;  // The dataset's folder, absolute.
  const Camera& left_camera() const override { return dataset_.left.camera; }
  const Camera& right_camera() const override { return dataset_.right->camera; }
  Rigid3d right_from_left() const override { return dataset_.right_from_left(); }
  int size() const override { return static_cast<int>(dataset_.frames.size()); }
  int64_t TimestampNs(int index) const override { return dataset_.frames[index].timestamp_ns; }
  StereoImages Read(int index) const override;
  cv::Mat ReadLeft(int index) const override;
  Map BuildMap(const MapBuilderOptions& options, const MapMetadata& metadata, MapBuildStats* stats,
               Trajectory* frame_trajectory, const MappingProgress& progress) const override;

 private:
  const Dataset& dataset_;
  std::string name_;
};

// Builds a map from every frame of a stereo dataset. `progress(done, total, status)` is called
// per frame. Throws InputError for monocular datasets, unreadable images, a rig that fails the
// check, or a map below options.min_points (the message names the reason and the evidence).
Map BuildMap(const Dataset& dataset, const DatasetMappingOptions& options,
             const MapMetadata& metadata, MapBuildStats* stats,
             Trajectory* frame_trajectory = nullptr,
             const std::function<void(int, int, const std::string&)>& progress = nullptr);

}  // namespace visloc::mapping
