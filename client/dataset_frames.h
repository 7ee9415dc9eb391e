#pragma once
// One dataset frame as the localization engine takes it (timestamp, odometry pose, the gyro
// samples since the previous frame), for `visloc localize` and `visloc stream` alike. The
// image is left to the caller: decoded in-process, or sent as the file's bytes.

#include "core/localization/localizer.h"
#include "dataset/dataset.h"

namespace visloc::cli {

FrameInput DatasetFrameInput(const Dataset& dataset, size_t index, bool odometry, bool gyro);

}  // namespace visloc::cli
