#pragma once
// When visloc_ros_node sends an image: once the odometry and the IMU it goes with have caught
// up with its stamp. Sensor messages travel on their own topics and often arrive a little after
// the image of the same instant. An image sent before then would carry an earlier frame's
// odometry as its own, a whole frame's motion missing from the prediction, and the next one
// twice that motion: its fix would disagree with the filter's prediction (the innovation gate,
// localizer_options.h) for no fault of its own and be held. So an image waits, a bounded
// while, for a message at or past its stamp from each sensor it uses. A sensor that has gone
// quiet is not waited for. Plain C++ (wall times in seconds, stamps in ns), unit-tested
// without ROS.

#include <cstddef>
#include <cstdint>
#include <deque>
#include <utility>
#include <vector>

namespace visloc::ros_node {

struct SensorSyncOptions {
  bool odometry = false;       // Wait for odometry stamped at or past the image.
  bool imu = false;            // Wait for an IMU sample stamped at or past the image.
  // A rig's further cameras: wait for an image of each stamped at or past the image's stamp
  // less camera_tolerance_ns (the same moment, as the engine's rig skew allows).
  size_t cameras = 0;
  int64_t camera_tolerance_ns = 5'000'000;
  double max_wait_s = 0.1;     // Wall time an image waits at most.
  double quiet_after_s = 1.0;  // A sensor without a message for this long is not waited for.
  size_t max_pending = 8;      // Images waiting at most; beyond it the oldest goes at once.
};

// The sensors' progress, and whether an image may go.
class SensorGate {
 public:
  explicit SensorGate(const SensorSyncOptions& options)
      : options_(options), cameras_(options.cameras) {}
  void OnOdometry(int64_t stamp_ns, double now_s) { odometry_.Heard(stamp_ns, now_s); }
  void OnImu(int64_t stamp_ns, double now_s) { imu_.Heard(stamp_ns, now_s); }
  // An image of rig camera `camera` (0-based among the further cameras).
  void OnCamera(size_t camera, int64_t stamp_ns, double now_s) {
    cameras_.at(camera).Heard(stamp_ns, now_s);
  }
  // True once every sensor the image waits for has reached its stamp (or is quiet), or it has
  // waited max_wait_s since `received_s`.
  bool MayRelease(int64_t stamp_ns, double received_s, double now_s) const;
  const SensorSyncOptions& options() const { return options_; }

 private:
  struct Sensor {
    void Heard(int64_t stamp_ns, double now_s);
    bool Reached(int64_t stamp_ns, double now_s, double quiet_after_s) const;
    bool heard = false;
    int64_t newest_ns = 0;
    double last_heard_s = 0.0;
  };
  SensorSyncOptions options_;
  Sensor odometry_, imu_;
  std::vector<Sensor> cameras_;
};

// Images (of any type) in the order they came, let go in that order as the gate allows.
template <typename Image>
class SensorSync {
 public:
  explicit SensorSync(const SensorSyncOptions& options) : gate_(options) {}
  SensorGate& gate() { return gate_; }

  void Add(int64_t stamp_ns, Image image, double now_s) {
    pending_.push_back({stamp_ns, now_s, std::move(image)});
  }

  // The images that may go now, oldest first. An image never overtakes an older one: the
  // engine needs its frames in time order.
  std::vector<Image> TakeReady(double now_s) {
    std::vector<Image> ready;
    while (!pending_.empty() &&
           (pending_.size() > gate_.options().max_pending ||
            gate_.MayRelease(pending_.front().stamp_ns, pending_.front().received_s, now_s))) {
      ready.push_back(std::move(pending_.front().image));
      pending_.pop_front();
    }
    return ready;
  }

  size_t pending() const { return pending_.size(); }

 private:
  struct Pending {
    int64_t stamp_ns;
    double received_s;
    Image image;
  };
  SensorGate gate_;
  std::deque<Pending> pending_;
};

}  // namespace visloc::ros_node
