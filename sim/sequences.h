#pragma once
// The catalogue of synthetic sequences and the stereo rig that films them.
//
// Every sequence lives in the same world frame; the *map frame* (product.md) is the left
// camera frame of the first frame of `map_square`, so ground truth of every sequence can be
// given in the map frame, as the localization tests need.

#include <string>
#include <utility>
#include <vector>

#include "dataset/dataset.h"
#include "sim/renderer.h"
#include "sim/walking_path.h"
#include "sim/world.h"

namespace visloc::sim {

struct RigOptions {
  int width = 320;
  int height = 240;
  double horizontal_fov_deg = 90.0;  // The paper's HRP-2 cameras (pinhole lenses).
  // Equidistant fisheye lenses instead, whose image diagonal spans fisheye_fov_deg (below 180).
  bool fisheye = false;
  double fisheye_fov_deg = 170.0;
  double baseline_m = 0.144;
  // Lens distortion: mild barrel distortion with small tangential terms (pinhole), or non-zero
  // k1..k4 (fisheye); different for the two cameras.
  bool distortion = false;
  // Like a real rig (EuRoC's VI-Sensor): each camera with its own focal lengths and principal
  // point, and the right camera turned by a fraction of a degree, its baseline a few
  // millimetres off axis. Rectification must undo all of it.
  bool imperfect = false;
  // The right camera is really turned about its y axis by this much against what its
  // calibration (the one written with the sequence) says: the yaw error a stereo calibration
  // leaves, which rectification cannot undo. It shifts every disparity by about
  // f tan(angle) pixels (KITTI 01's rig behaves as if by 0.1 deg: 1.3 px), and a map that
  // trusts the calibration comes out metrically wrong, most where disparities are small.
  double right_yaw_error_deg = 0.0;
  // The stereo pair mounted tilted on the head, turned about the body origin: pitched down by
  // this much (about the body's y axis) and rolled right (about its x axis). A map's frame is
  // its first left camera's, so a tilted pair gives a map frame that is not level.
  double camera_pitch_deg = 0.0;
  double camera_roll_deg = 0.0;
  double fps = 15.0;
  // Further cameras on the head beside the stereo pair, with the left camera's lens
  // (OtherCameras): none; a rear one (front-back); rear, left and right ones (four).
  enum class Layout { kStereo, kFrontBack, kFour };
  Layout layout = Layout::kStereo;
};

// "stereo", "front-back" or "four"; throws InputError otherwise.
RigOptions::Layout ParseRigLayout(const std::string& name);
const char* RigLayoutName(RigOptions::Layout layout);

// A car's stereo rig with KITTI's geometry: 1241x376 pixels, a 719 px focal length, a 0.54 m
// baseline, 10 Hz. The error settings of `base` (right_yaw_error_deg) are kept.
RigOptions CarRig(const RigOptions& base);

struct StereoRig {
  CameraInfo left;
  CameraInfo right;
};

// Cameras mounted on the head: the left camera 0.072 m left of the body origin, the right one
// 0.072 m right, both looking along the body's x axis (camera z = body x, camera x = -body y).
StereoRig MakeRig(const RigOptions& options);

// One stereo shot of `world` by `rig` with the head at `world_from_body`: both images as
// `sensor` captures them (8-bit grey, noise from `noise`), and the left camera's rendered depth
// (metres along its z axis, 0 where nothing is seen). For tests and benchmarks of stereo matching.
struct StereoShot {
  cv::Mat left, right, left_depth;
};
StereoShot RenderStereoShot(const World& world, const StereoRig& rig,
                            const Rigid3d& world_from_body, const SensorModel& sensor, Rng* noise,
                            int supersample = 2);

// The layout's further cameras (cam2, cam3, ...): the rear camera 0.1 m behind the head's
// centre looking back (front-back), then one on each side looking left and right (four).
std::vector<CameraInfo> OtherCameras(const RigOptions& options, const StereoRig& rig);

struct SequenceSpec {
  std::string name;
  std::string description;
  RoomOptions room;
  WalkingPath path;
  SensorModel sensor;
  std::vector<std::pair<double, double>> covered_s;  // Camera covered during these intervals.
  // The front pair faces a blank wall during these: a textureless surface fills its view (the
  // rig's further cameras see the room).
  std::vector<std::pair<double, double>> blank_s;
  // Filmed by CarRig instead of the generator's rig; its map frame is its own first frame.
  bool car = false;
};

// Names in catalogue order: map_square, query_square, straight, circle, outward, glances,
// kidnap, blankwall, lowlight, occluders, changed, outofmap, map_suite, query_suite, drive. The
// suite sequences start where map_square does, so a map built from map_suite has the same map
// frame.
const std::vector<std::string>& SequenceNames();

// Throws InputError for an unknown name (listing the known ones).
SequenceSpec MakeSequenceSpec(const std::string& name, uint64_t seed);

// The map frame in the world: the left camera's pose at the first frame of map_square.
Rigid3d WorldFromMap(const RigOptions& rig);

}  // namespace visloc::sim
