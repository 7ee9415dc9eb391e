#pragma once
// One dataset frame as the localization engine takes it (timestamp, odometry pose, the gyro
// samples since the previous frame), for `visloc localize` and `visloc stream` alike. The
// image is left to the caller: decoded in-process, or sent as the file's bytes.

#include "core/localization/localizer.h"
#include "dataset/dataset.h"

namespace visloc::cli {

// Reads a query dataset for the engine: `format` empty means detected; with `odometry` the
// dataset must carry odometry (InputError naming the folder otherwise).
Dataset ReadQueryDataset(const std::string& dir, const std::string& format, bool odometry);

// Frame `index`: odometry pose (with `odometry`) and the gyro samples after the previous frame up
// to this one (with `gyro`; found by binary search, the samples being sorted by time).
FrameInput DatasetFrameInput(const Dataset& dataset, size_t index, bool odometry, bool gyro);

}  // namespace visloc::cli
