#include "ros/node/sensor_sync.h"

#include <gtest/gtest.h>

#include <vector>

namespace visloc::ros_node {
namespace {

constexpr int64_t kFrameNs = 66'666'667;  // A 15 Hz camera.

SensorSyncOptions WaitingFor(bool odometry, bool imu) {
  SensorSyncOptions options;
  options.odometry = odometry;
  options.imu = imu;
  return options;
}
SensorSyncOptions WaitingForOdometry() { return WaitingFor(true, false); }

TEST(SensorSyncTest, AnImageWaitsForTheOdometryOfItsOwnStamp) {
  // The odometry of frame 1 arrives 5 ms after its image, as a bag or a robot publishes them.
  SensorSync<int> sync(WaitingForOdometry());
  sync.gate().OnOdometry(0, 0.000);
  sync.Add(kFrameNs, 1, 0.066);
  EXPECT_TRUE(sync.TakeReady(0.067).empty()) << "sent with frame 0's odometry as its own";
  sync.gate().OnOdometry(kFrameNs, 0.071);
  EXPECT_EQ(sync.TakeReady(0.071), std::vector<int>{1});
  EXPECT_EQ(sync.pending(), 0u);
}

TEST(SensorSyncTest, OdometryAlreadyPastTheImageLetsItGoAtOnce) {
  SensorSync<int> sync(WaitingForOdometry());
  sync.gate().OnOdometry(2 * kFrameNs, 0.100);  // 50 Hz odometry runs ahead of the camera.
  sync.Add(kFrameNs, 1, 0.101);
  EXPECT_EQ(sync.TakeReady(0.101), std::vector<int>{1});
}

TEST(SensorSyncTest, EverySensorInUseMustReachTheStamp) {
  SensorSync<int> sync(WaitingFor(true, true));
  sync.gate().OnImu(0, 0.0);
  sync.gate().OnOdometry(kFrameNs, 0.060);
  sync.Add(kFrameNs, 1, 0.066);
  EXPECT_TRUE(sync.TakeReady(0.066).empty()) << "the gyro samples up to the stamp are not in";
  sync.gate().OnImu(kFrameNs + 1'000'000, 0.068);
  EXPECT_EQ(sync.TakeReady(0.068), std::vector<int>{1});
}

TEST(SensorSyncTest, TheWaitIsBounded) {
  SensorSyncOptions options = WaitingForOdometry();
  options.max_wait_s = 0.1;
  SensorSync<int> sync(options);
  sync.gate().OnOdometry(0, 0.0);
  sync.Add(kFrameNs, 1, 0.066);
  EXPECT_TRUE(sync.TakeReady(0.150).empty());
  EXPECT_EQ(sync.TakeReady(0.166), std::vector<int>{1});  // 100 ms: sent without it.
}

TEST(SensorSyncTest, AQuietOrAbsentSensorIsNotWaitedFor) {
  SensorSyncOptions options = WaitingForOdometry();
  options.quiet_after_s = 1.0;
  SensorSync<int> sync(options);
  sync.Add(0, 1, 0.0);  // No odometry ever: no wait.
  EXPECT_EQ(sync.TakeReady(0.0), std::vector<int>{1});
  sync.gate().OnOdometry(0, 0.0);
  sync.Add(kFrameNs, 2, 1.5);  // The odometry stopped 1.5 s ago.
  EXPECT_EQ(sync.TakeReady(1.5), std::vector<int>{2});
}

TEST(SensorSyncTest, ImagesGoInTheOrderTheyCameAndTheQueueIsBounded) {
  SensorSyncOptions options = WaitingForOdometry();
  options.max_pending = 2;
  SensorSync<int> sync(options);
  sync.gate().OnOdometry(0, 0.0);
  sync.Add(1 * kFrameNs, 1, 0.010);
  sync.Add(2 * kFrameNs, 2, 0.011);
  EXPECT_TRUE(sync.TakeReady(0.012).empty());
  sync.Add(3 * kFrameNs, 3, 0.012);  // Three waiting, two allowed: the oldest goes.
  EXPECT_EQ(sync.TakeReady(0.012), std::vector<int>{1});
  // Odometry for frame 3 (not 2 alone) releases both, in order.
  sync.gate().OnOdometry(3 * kFrameNs, 0.013);
  EXPECT_EQ(sync.TakeReady(0.013), (std::vector<int>{2, 3}));
}

TEST(SensorSyncTest, AnOlderStampArrivingLateDoesNotMoveTheSensorBack) {
  SensorSync<int> sync(WaitingForOdometry());
  sync.gate().OnOdometry(2 * kFrameNs, 0.0);
  sync.gate().OnOdometry(1 * kFrameNs, 0.001);
  sync.Add(2 * kFrameNs, 1, 0.002);
  EXPECT_EQ(sync.TakeReady(0.002), std::vector<int>{1});
}

// A rig: the reference camera's image waits for the other cameras' images of the same moment
// (their stamps within the tolerance, on either side), which their topics may bring later.
TEST(SensorSyncTest, ARigsImageWaitsForItsOtherCamerasImagesOfTheSameMoment) {
  SensorSyncOptions options;
  options.cameras = 2;
  SensorSync<int> sync(options);
  sync.gate().OnCamera(0, 0, 0.000);
  sync.gate().OnCamera(1, 0, 0.000);
  sync.Add(kFrameNs, 1, 0.066);
  sync.gate().OnCamera(0, kFrameNs - 2'000'000, 0.068);  // 2 ms earlier: the same moment.
  EXPECT_TRUE(sync.TakeReady(0.068).empty()) << "sent without camera 2's image";
  sync.gate().OnCamera(1, kFrameNs + 1'000'000, 0.070);
  EXPECT_EQ(sync.TakeReady(0.070), std::vector<int>{1});
  EXPECT_THROW(sync.gate().OnCamera(2, 0, 0.1), std::out_of_range);
}

}  // namespace
}  // namespace visloc::ros_node
