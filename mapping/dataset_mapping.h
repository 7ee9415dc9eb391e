#pragma once
// Feeds a recorded stereo sequence (dataset/) to the MapBuilder: the dataset driver that `visloc
// map build` and the tests use. The builder itself knows nothing of datasets or files.

#include <functional>
#include <string>

#include "dataset/dataset.h"
#include "mapping/map_builder.h"

namespace visloc::mapping {

// Builds a map from every frame of a stereo dataset. `progress(done, total, status)` is called
// per frame. Throws InputError for monocular datasets or unreadable images.
Map BuildMap(const Dataset& dataset, const MapBuilderOptions& options, const MapMetadata& metadata,
             MapBuildStats* stats, Trajectory* frame_trajectory = nullptr,
             const std::function<void(int, int, const std::string&)>& progress = nullptr);

}  // namespace visloc::mapping
