#pragma once
// The KITTI odometry layout (Geiger et al., CVPR 2012):
//
//   DIR/image_0/000000.png ...   left grey camera (rectified)
//   DIR/image_1/000000.png ...   right grey camera (rectified, optional)
//   DIR/calib.txt                "P0: 12 numbers" ... 3x4 projection matrices, row-major
//   DIR/times.txt                one timestamp per frame, seconds
//   DIR/poses.txt or DIR/../../poses/<DIR name>.txt   optional: 12 numbers per frame, the
//                                left camera's pose in the first frame (map_from_cam, 3x4)
//
// KITTI images are already rectified, so the cameras have no distortion and the right camera
// sits at x = baseline = -P1(0,3) / P1(0,0) in the left camera frame. The "body" frame of the
// returned Dataset is the left camera.

#include <string>

#include <opencv2/core.hpp>

#include "dataset/dataset.h"

namespace visloc {

Dataset ReadKitti(const std::string& dir);

// Writes a rectified stereo sequence in the KITTI layout (times, calib, images, poses.txt).
// `left_cam_poses` holds the left camera's poses in its first frame, one per frame, or is
// empty. Used by the simulator and the reader's tests.
void WriteKittiCalibration(const std::string& dir, const Camera& camera, double baseline_m);
void WriteKittiFrame(const std::string& dir, int index, const cv::Mat& left, const cv::Mat& right);
void WriteKittiTimesAndPoses(const std::string& dir, const std::vector<int64_t>& timestamps_ns,
                             const Trajectory& left_cam_poses);

}  // namespace visloc
