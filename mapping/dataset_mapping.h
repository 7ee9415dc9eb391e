#pragma once
// Feeds a recorded stereo sequence (dataset/) to the MapBuilder: the dataset driver that `visloc
// map build` and the tests use. The builder itself knows nothing of datasets or files.

#include <functional>
#include <string>

#include "dataset/dataset.h"
#include "mapping/dataset_check.h"
#include "mapping/map_builder.h"

namespace visloc::mapping {

struct DatasetMappingOptions {
  MapBuilderOptions builder;
  // Before the build, the rig is checked on this many frames (CheckDataset); a rig that would
  // not map is refused with the reason. 0 skips the check.
  int check_frames = 3;
  // A map with fewer points is refused, with the stereo evidence, rather than written.
  int min_points = 100;
  void Check() const;
};

// Builds a map from every frame of a stereo dataset. `progress(done, total, status)` is called
// per frame. Throws InputError for monocular datasets, unreadable images, a rig that fails the
// check, or a map below options.min_points (the message names the reason and the evidence).
Map BuildMap(const Dataset& dataset, const DatasetMappingOptions& options,
             const MapMetadata& metadata,
             MapBuildStats* stats, Trajectory* frame_trajectory = nullptr,
             const std::function<void(int, int, const std::string&)>& progress = nullptr);

}  // namespace visloc::mapping
