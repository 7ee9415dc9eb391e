#include "client/dataset_frames.h"

#include <algorithm>

#include "core/util/args.h"
#include "core/util/check.h"
#include "core/util/strings.h"
#include "proto/geometry_convert.h"

namespace visloc::cli {

Dataset ReadQueryDataset(const std::string& dir, const std::string& format, bool odometry) {
  Dataset dataset = ReadDataset(dir, ParseOptionalDatasetFormat(format));
  if (odometry && dataset.odom_from_cam.empty()) {
    throw InputError(dir + ": --odometry given but the dataset has no odometry");
  }
  return dataset;
}

FrameInput DatasetFrameInput(const Dataset& dataset, size_t index, bool odometry, bool gyro) {
  const FrameRecord& record = dataset.frames[index];
  FrameInput input;
  input.timestamp_ns = record.timestamp_ns;
  if (odometry) {
    input.odom_from_cam =
        InterpolateAt(dataset.odom_from_cam, record.timestamp_ns, SecondsToNs(0.2));
  }
  if (gyro) {
    const int64_t previous =
        index > 0 ? dataset.frames[index - 1].timestamp_ns : record.timestamp_ns;
    const auto after = [](const ImuSample& s, int64_t t) { return s.timestamp_ns <= t; };
    auto it = std::lower_bound(dataset.imu.begin(), dataset.imu.end(), previous, after);
    for (; it != dataset.imu.end() && it->timestamp_ns <= record.timestamp_ns; ++it) {
      input.gyro.push_back({it->timestamp_ns, it->gyro_radps});
    }
  }
  return input;
}

std::vector<std::string> ParseCameraNames(const std::string& list) {
  std::vector<std::string> names = Split(list, ',');
  if (names.empty() || names.front() != "cam0") {
    throw UsageError("--cameras starts with cam0, the reference camera (got '" + list + "')");
  }
  if (names.size() > CameraRig::kMaxCameras) {
    throw UsageError(StrCat("--cameras: at most ", CameraRig::kMaxCameras, " cameras"));
  }
  for (size_t i = 0; i < names.size(); ++i) {
    if (std::find(names.begin(), names.begin() + i, names[i]) != names.begin() + i) {
      throw UsageError("--cameras names " + names[i] + " twice");
    }
  }
  return names;
}

namespace {

const CameraStream* FindStream(const Dataset& dataset, const std::string& name) {
  for (const CameraStream& stream : dataset.other_cameras) {
    if (stream.name == name) return &stream;
  }
  return nullptr;
}

const CameraInfo& CameraNamed(const Dataset& dataset, const std::string& name) {
  if (name == "cam0") return dataset.left;
  if (name == "cam1" && dataset.right) return *dataset.right;
  if (const CameraStream* stream = FindStream(dataset, name)) return stream->info;
  std::string known = dataset.right ? "cam0, cam1" : "cam0";
  for (const CameraStream& stream : dataset.other_cameras) known += ", " + stream.name;
  throw InputError(dataset.root + ": no camera " + name + " (it has " + known + ")");
}

}  // namespace

CameraRig DatasetCameraRig(const Dataset& dataset, const std::vector<std::string>& names,
                           bool gyro) {
  CameraRig rig;
  for (const std::string& name : names) {
    const CameraInfo& info = CameraNamed(dataset, name);
    rig.cameras.push_back(info.camera);
    rig.body_from_cam.push_back(info.body_from_cam);
  }
  rig.body_is_gyro_frame = gyro;
  return rig;
}

std::optional<std::pair<int64_t, std::string>> CameraImageAt(const Dataset& dataset,
                                                             const std::string& name, size_t index,
                                                             int64_t tolerance_ns) {
  const FrameRecord& record = dataset.frames[index];
  if (name == "cam0") return std::make_pair(record.timestamp_ns, record.left_path);
  if (name == "cam1" && dataset.right) {
    return std::make_pair(record.timestamp_ns, record.right_path);
  }
  const CameraStream* stream = FindStream(dataset, name);
  if (stream == nullptr) CameraNamed(dataset, name);  // Throws, naming the cameras there are.
  const auto* image = stream->Nearest(record.timestamp_ns, tolerance_ns);
  if (image == nullptr) return std::nullopt;
  return *image;
}

std::vector<v1::RigCamera> WireRigCameras(const CameraRig& rig,
                                          const std::vector<std::string>& names) {
  std::vector<v1::RigCamera> cameras;
  for (size_t c = 1; c < rig.cameras.size(); ++c) {
    v1::RigCamera& camera = cameras.emplace_back();
    proto::ToProto(rig.cameras[c], camera.mutable_camera());
    proto::ToProto(rig.body_from_cam[c], camera.mutable_body_from_cam());
    camera.set_name(names[c]);
  }
  return cameras;
}

}  // namespace visloc::cli
