#pragma once
// The EuRoC/ASL layout (Burri et al., IJRR 2016), as product.md specifies:
//
//   DIR/mav0/cam0/{data.csv, sensor.yaml, data/<timestamp>.png}   left camera (reference)
//   DIR/mav0/cam1/...                                             right camera (optional)
//   DIR/mav0/cam2/..., cam3/, ...                                 a rig's further cameras
//   DIR/mav0/imu0/{data.csv, sensor.yaml}                         gyro + accelerometer (optional)
//   DIR/mav0/odometry0/data.csv                                   odometry poses (optional)
//   DIR/mav0/state_groundtruth_estimate0/data.csv                 ground truth (optional)
//
// sensor.yaml carries T_BS (body_from_sensor, row-major 4x4), rate_hz, resolution [w, h],
// camera_model (pinhole), intrinsics [fu, fv, cu, cv], distortion_model (radial-tangential
// or equidistant) and distortion_coefficients [k1, k2, p1, p2] or [k1, k2, k3, k4].

#include <string>

#include <opencv2/core.hpp>

#include "dataset/dataset.h"

namespace visloc {

Dataset ReadEuroc(const std::string& dir);

// Writes one camera's sensor.yaml (atomically). `comment` names the camera.
void WriteSensorYaml(const std::string& path, const CameraInfo& info, const std::string& comment);
// Reads one camera's sensor.yaml; throws InputError naming the file and line of a problem.
CameraInfo ReadSensorYaml(const std::string& path);

// Writes a dataset in the EuRoC layout. Images are written as frames are added, so a long
// sequence never has to be held in memory; Finish writes the CSV files.
class EurocWriter {
 public:
  // Creates the folder layout; `right` may be empty for a monocular sequence.
  EurocWriter(const std::string& dir, const CameraInfo& left,
              const std::optional<CameraInfo>& right);

  // A further camera of the rig (cam2, cam3, ... in the order added), before the first frame.
  void AddCamera(const CameraInfo& info, const std::string& comment);
  // `left` (and `right` when stereo) are 8-bit grey images of the calibrated size, `others`
  // one per added camera, taken at the same moment.
  void AddFrame(int64_t timestamp_ns, const cv::Mat& left, const cv::Mat& right,
                const std::vector<cv::Mat>& others = {});
  // Writes data.csv for the cameras and the optional streams (empty ones are not written).
  void Finish(const std::vector<ImuSample>& imu, const Trajectory& odom_from_cam,
              const Trajectory& world_from_body);

 private:
  std::string mav0_;
  CameraInfo left_;
  std::optional<CameraInfo> right_;
  std::vector<CameraInfo> others_;
  std::vector<int64_t> timestamps_ns_;
};

}  // namespace visloc
