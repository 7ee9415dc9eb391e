#pragma once
// One dataset frame as the localization engine takes it (timestamp, odometry pose, the gyro
// samples since the previous frame), for `visloc localize` and `visloc stream` alike. The
// image is left to the caller: decoded in-process, or sent as the file's bytes.

#include "core/localization/localizer.h"
#include "dataset/dataset.h"
#include "visloc/v1/visloc.pb.h"

namespace visloc::cli {

// Reads a query dataset for the engine: `format` empty means detected; with `odometry` the
// dataset must carry odometry (InputError naming the folder otherwise).
Dataset ReadQueryDataset(const std::string& dir, const std::string& format, bool odometry);

// Frame `index`: odometry pose (with `odometry`) and the gyro samples after the previous frame up
// to this one (with `gyro`; found by binary search, the samples being sorted by time).
FrameInput DatasetFrameInput(const Dataset& dataset, size_t index, bool odometry, bool gyro);

// Camera names of `--cameras` ("cam0,cam2"): cam0 first (the reference, whose pose is
// reported), each once. Throws UsageError otherwise.
std::vector<std::string> ParseCameraNames(const std::string& list);

// The dataset's cameras `names` as a rig: cam0 is the left camera, cam1 the stereo pair's right,
// cam2 and after EuRoC's further cameras; their T_BS place them on the body (the gyro's frame
// with `gyro`). Throws InputError naming a camera the dataset does not have.
CameraRig DatasetCameraRig(const Dataset& dataset, const std::vector<std::string>& names,
                           bool gyro);

// Camera `name`'s image of frame `index`: its stamp and file, or none when it has no image
// within `tolerance_ns` of the frame's stamp.
std::optional<std::pair<int64_t, std::string>> CameraImageAt(const Dataset& dataset,
                                                             const std::string& name, size_t index,
                                                             int64_t tolerance_ns);

// A rig's other cameras (cameras 1.., named names[1..]) on the wire, each placed on the body by
// its body_from_cam (T_BS): the body of the reference camera's, which the session (or request)
// then declares.
std::vector<v1::RigCamera> WireRigCameras(const CameraRig& rig,
                                          const std::vector<std::string>& names);

}  // namespace visloc::cli
