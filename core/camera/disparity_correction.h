#pragma once
// What a stereo rig's disparities do beyond its calibration. Rectification makes the two
// cameras' rows agree, so any calibration error that moves points across rows shows (the
// epipolar residual of `visloc dataset check`). Two errors move points only along their rows
// and are invisible to it: the right camera's principal point off in x, and the right camera
// turned about its y axis (its yaw, the one angle stereo calibration determines worst, and
// the one a rig's mount drifts in). Both bias every disparity:
//
//   measured - true = offset_px + f yaw_rad (1 + x^2),
//
// with x = (u_right - cx) / f the right image's normalized rectified x (to first order in the
// yaw). A bias of a pixel is a 5% depth error at 20 px of disparity and 50% at 2 px: a map
// built with it is metrically wrong, most where points are far (KITTI 01 behaves as if its
// right camera were turned by 0.1 degree: 1.3 px). Motion observes it: the same point seen
// from places the camera drove between must have the depths its disparities say.
//
// A property of the rig, not of one build: a map records the correction it was built with
// (MapMetadata), so the rig's next builds and the sessions that extend the map can take it.

#include <cmath>

namespace visloc {

struct DisparityCorrection {
  double offset_px = 0.0;
  double yaw_rad = 0.0;

  // Users and the wire give the yaw in degrees (a build's right_camera_yaw_deg).
  static DisparityCorrection FromDegrees(double offset_px, double yaw_deg) {
    return {offset_px, yaw_deg * M_PI / 180.0};
  }
  double yaw_deg() const { return yaw_rad * 180.0 / M_PI; }

  // The bias of a disparity measured at right image column `right_x_px` (rectified pixels), for
  // the rectified focal length `f_px` and principal point `cx_px`.
  double BiasPx(double right_x_px, double f_px, double cx_px) const {
    const double x = (right_x_px - cx_px) / f_px;
    return offset_px + f_px * yaw_rad * (1.0 + x * x);
  }
  bool operator==(const DisparityCorrection& other) const {
    return offset_px == other.offset_px && yaw_rad == other.yaw_rad;
  }
  bool operator!=(const DisparityCorrection& other) const { return !(*this == other); }
};

// Two small corrections, one after the other (exact for the offsets, first order in the yaws).
inline DisparityCorrection operator+(const DisparityCorrection& a, const DisparityCorrection& b) {
  return {a.offset_px + b.offset_px, a.yaw_rad + b.yaw_rad};
}

}  // namespace visloc
