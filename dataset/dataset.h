#pragma once
// In-memory description of a recorded (or generated) sequence, independent of its on-disk
// format. Readers fill it and validate it; images are decoded lazily with LoadGreyImage.
//
// Frames: `body` is the sensor rig's reference frame (EuRoC: the IMU), `cam` a camera frame
// (OpenCV convention), `world` the ground truth's fixed frame, `odom` the odometry's own fixed
// frame. Units: metres, radians, nanoseconds.

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "core/camera/camera.h"
#include "core/geometry/rigid3.h"
#include "core/geometry/trajectory.h"

namespace visloc {

enum class DatasetFormat { kEuroc, kKitti };
std::string ToString(DatasetFormat format);
// "euroc" or "kitti"; throws InputError otherwise.
DatasetFormat ParseDatasetFormat(const std::string& text);
// The same for a --format flag that may be left empty: none, the layout is detected.
std::optional<DatasetFormat> ParseOptionalDatasetFormat(const std::string& text);

struct CameraInfo {
  Camera camera;
  Rigid3d body_from_cam;
  double rate_hz = 0.0;
};

struct FrameRecord {
  int64_t timestamp_ns = 0;
  std::string left_path;
  std::string right_path;  // Empty for monocular datasets.
};

// One IMU sample in the body frame: angular rate (rad/s) and specific force (m/s^2).
struct ImuSample {
  int64_t timestamp_ns = 0;
  Eigen::Vector3d gyro_radps = Eigen::Vector3d::Zero();
  Eigen::Vector3d accel_mps2 = Eigen::Vector3d::Zero();
};

// How the left and right images were paired into stereo frames (by timestamp).
struct StereoPairing {
  int unpaired_left = 0;      // Left images with no right image close enough in time: left out.
  int unpaired_right = 0;     // Right images with no left image: left out.
  int64_t max_offset_ns = 0;  // Largest time difference within a pair.
};

// A further camera of the recording's rig (EuRoC cam2, cam3, ...): its calibration and its
// images, each with its own stamp, not paired with the stereo frames.
struct CameraStream {
  std::string name;  // The folder's: "cam2".
  CameraInfo info;
  std::vector<std::pair<int64_t, std::string>> images;  // Stamp (ns) and path, increasing.
  // The image whose stamp is nearest `timestamp_ns`, when within `tolerance_ns`; else nullptr.
  const std::pair<int64_t, std::string>* Nearest(int64_t timestamp_ns, int64_t tolerance_ns) const;
};

struct Dataset {
  std::string root;
  DatasetFormat format = DatasetFormat::kEuroc;
  CameraInfo left;
  std::optional<CameraInfo> right;
  std::vector<FrameRecord> frames;  // Strictly increasing timestamps.
  std::vector<ImuSample> imu;       // Empty when the dataset has none.
  Trajectory odom_from_cam;         // Odometry's camera poses; only relative motion matters.
  Trajectory world_from_body;       // Ground truth; empty when the dataset has none.
  StereoPairing pairing;            // Stereo datasets only.
  std::vector<CameraStream> other_cameras;  // EuRoC's cam2, cam3, ... in order.

  bool has_stereo() const { return right.has_value(); }
  // Maps left-camera coordinates into the right camera. Requires has_stereo().
  Rigid3d right_from_left() const;
  // Ground-truth left-camera poses at the frame timestamps (interpolated, frames without
  // ground truth within 50 ms are left out).
  Trajectory GroundTruthLeftCam() const;
};

// Decodes an image file (PNG or JPEG, grey or colour) to 8-bit grey. Throws InputError naming
// the file when it is missing, undecodable, or not `expected_width` x `expected_height` (0 x 0:
// any size).
cv::Mat LoadGreyImage(const std::string& path, int expected_width, int expected_height);

// Reads a dataset; without `format` the layout is detected (mav0/ for EuRoC, image_0/ for
// KITTI). Throws InputError naming the file (and line) of the first problem found.
Dataset ReadDataset(const std::string& dir, std::optional<DatasetFormat> format = std::nullopt);

}  // namespace visloc
