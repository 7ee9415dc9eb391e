#include "client/dataset_frames.h"

namespace visloc::cli {

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
    for (const ImuSample& s : dataset.imu) {
      if (s.timestamp_ns > previous && s.timestamp_ns <= record.timestamp_ns) {
        input.gyro.push_back({s.timestamp_ns, s.gyro_radps});
      }
    }
  }
  return input;
}

}  // namespace visloc::cli
