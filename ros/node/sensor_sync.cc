#include "ros/node/sensor_sync.h"

#include <algorithm>

namespace visloc::ros_node {

void SensorGate::Sensor::Heard(int64_t stamp_ns, double now_s) {
  newest_ns = heard ? std::max(newest_ns, stamp_ns) : stamp_ns;
  heard = true;
  last_heard_s = now_s;
}

bool SensorGate::Sensor::Reached(int64_t stamp_ns, double now_s, double quiet_after_s) const {
  // Never heard, or silent for a while: waiting would only add latency to every frame.
  if (!heard || now_s - last_heard_s > quiet_after_s) return true;
  return newest_ns >= stamp_ns;
}

bool SensorGate::MayRelease(int64_t stamp_ns, double received_s, double now_s) const {
  if (now_s - received_s >= options_.max_wait_s) return true;
  for (const Sensor& camera : cameras_) {
    if (!camera.Reached(stamp_ns - options_.camera_tolerance_ns, now_s, options_.quiet_after_s)) {
      return false;
    }
  }
  return (!options_.odometry || odometry_.Reached(stamp_ns, now_s, options_.quiet_after_s)) &&
         (!options_.imu || imu_.Reached(stamp_ns, now_s, options_.quiet_after_s));
}

}  // namespace visloc::ros_node
