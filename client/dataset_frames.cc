#include "client/dataset_frames.h"

#include <algorithm>

#include "core/util/check.h"

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

}  // namespace visloc::cli
