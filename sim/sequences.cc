#include "sim/sequences.h"

#include <cmath>

#include "core/util/check.h"

namespace visloc::sim {

namespace {

// The ideal camera of the rig's lens, with the lens coefficients of one of its two cameras.
Camera RigCamera(const RigOptions& options, bool left) {
  const Camera ideal =
      options.fisheye
          ? Camera::FisheyeFromDiagonalFov(options.width, options.height, options.fisheye_fov_deg)
          : Camera::FromHorizontalFov(options.width, options.height, options.horizontal_fov_deg);
  Lens lens = ideal.lens();
  if (options.distortion) {
    if (options.fisheye) {
      lens = left ? Lens::Equidistant(0.012, -0.004, 0.001, -0.0002)
                  : Lens::Equidistant(0.010, -0.003, 0.0008, -0.0001);
    } else {
      lens = left ? Lens(-0.12, 0.018, 4e-4, -3e-4) : Lens(-0.11, 0.016, -2e-4, 5e-4);
    }
  }
  double fx = ideal.fx(), fy = ideal.fy(), cx = ideal.cx(), cy = ideal.cy();
  if (options.imperfect) {
    // Relative to the image size, so every resolution gets the same rig: a focal length 0.4 to
    // 0.8 % off, principal points a percent of the image off centre.
    const double w = options.width, h = options.height;
    fx *= left ? 1.004 : 0.992;
    fy *= left ? 0.998 : 0.995;
    cx += (left ? 0.007 : -0.010) * w;
    cy += (left ? -0.007 : 0.010) * h;
  }
  return Camera(options.width, options.height, fx, fy, cx, cy, lens);
}

}  // namespace

StereoRig MakeRig(const RigOptions& options) {
  VISLOC_CHECK(options.width >= 16 && options.height >= 16, "resolution ", options.width, "x",
               options.height);
  VISLOC_CHECK(options.fps > 0 && options.baseline_m > 0, "fps ", options.fps, " baseline ",
               options.baseline_m);
  Eigen::Matrix3d body_from_cam_rotation;
  // Columns: the camera's x, y, z axes in the body frame.
  body_from_cam_rotation << 0, 0, 1,  //
      -1, 0, 0,                       //
      0, -1, 0;
  StereoRig rig;
  rig.left.camera = RigCamera(options, /*left=*/true);
  rig.left.body_from_cam =
      Rigid3d(body_from_cam_rotation, Eigen::Vector3d(0, options.baseline_m / 2, 0));
  rig.left.rate_hz = options.fps;
  rig.right = rig.left;
  rig.right.camera = RigCamera(options, /*left=*/false);
  rig.right.body_from_cam.translation = Eigen::Vector3d(0, -options.baseline_m / 2, 0);
  if (options.imperfect) {
    // EuRoC's two cameras are turned about 0.5 deg against each other.
    rig.right.body_from_cam.rotation =
        rig.right.body_from_cam.rotation *
        RotationFromRollPitchYaw(0.35 * M_PI / 180, -0.45 * M_PI / 180, 0.25 * M_PI / 180);
    rig.right.body_from_cam.translation += Eigen::Vector3d(0.0015, 0.0, 0.002);
  }
  if (options.camera_pitch_deg != 0 || options.camera_roll_deg != 0) {
    // Roll about body x, then pitch about body y (positive: the optical axis down).
    const Rigid3d tilt(RotationFromRollPitchYaw(options.camera_roll_deg * M_PI / 180,
                                                options.camera_pitch_deg * M_PI / 180, 0),
                       Eigen::Vector3d::Zero());
    rig.left.body_from_cam = tilt * rig.left.body_from_cam;
    rig.right.body_from_cam = tilt * rig.right.body_from_cam;
  }
  return rig;
}

RigOptions::Layout ParseRigLayout(const std::string& name) {
  if (name == "stereo") return RigOptions::Layout::kStereo;
  if (name == "front-back") return RigOptions::Layout::kFrontBack;
  if (name == "four") return RigOptions::Layout::kFour;
  throw InputError("unknown rig '" + name + "' (stereo, front-back or four)");
}

const char* RigLayoutName(RigOptions::Layout layout) {
  switch (layout) {
    case RigOptions::Layout::kStereo:
      return "stereo";
    case RigOptions::Layout::kFrontBack:
      return "front-back";
    case RigOptions::Layout::kFour:
      return "four";
  }
  return "?";
}

std::vector<CameraInfo> OtherCameras(const RigOptions& options, const StereoRig& rig) {
  // Each further camera is the left camera turned about the body's vertical (z) axis by
  // `yaw_rad`, at `position` on the head.
  const auto turned = [&](double yaw_rad, const Eigen::Vector3d& position) {
    CameraInfo info = rig.left;
    info.body_from_cam =
        Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ())) *
                    rig.left.body_from_cam.rotation,
                position);
    return info;
  };
  std::vector<CameraInfo> others;
  if (options.layout == RigOptions::Layout::kStereo) return others;
  others.push_back(turned(M_PI, Eigen::Vector3d(-0.1, 0.0, 0.0)));
  if (options.layout == RigOptions::Layout::kFour) {
    others.push_back(turned(M_PI / 2, Eigen::Vector3d(-0.05, 0.1, 0.0)));
    others.push_back(turned(-M_PI / 2, Eigen::Vector3d(-0.05, -0.1, 0.0)));
  }
  return others;
}

RigOptions CarRig(const RigOptions& base) {
  RigOptions car;
  car.width = 1241;
  car.height = 376;
  car.horizontal_fov_deg = 2.0 * std::atan(620.5 / 718.856) * 180.0 / M_PI;  // fx 718.856 px.
  car.baseline_m = 0.54;
  car.fps = 10.0;
  car.right_yaw_error_deg = base.right_yaw_error_deg;
  car.camera_pitch_deg = base.camera_pitch_deg;
  car.camera_roll_deg = base.camera_roll_deg;
  return car;
}

const std::vector<std::string>& SequenceNames() {
  static const std::vector<std::string> names = {
      "map_square", "query_square", "straight",  "circle",      "outward",
      "glances",    "kidnap",       "blankwall", "lowlight",    "occluders",
      "changed",    "outofmap",     "map_suite", "query_suite", "drive"};
  return names;
}

const std::vector<std::string>& LongSequenceNames() {
  static const std::vector<std::string> names = {"map_building"};
  return names;
}

namespace {

// The 2 m square, walked counter-clockwise from its south-west corner facing east, turning
// in place at the corners and closing the loop facing east again.
WalkingPath SquarePath(double x0, double y0, const GaitOptions& gait) {
  WalkingPath path({x0, y0, 0.0}, gait);
  for (int side = 0; side < 4; ++side) path.Walk(2.0).Turn(M_PI / 2);
  return path;
}

// From the crossing of the suite's lanes, a visit to one neighbouring room: walk 7.5 m through
// its doorway (to about 3 m inside), look left, right and back, and walk back to the crossing,
// ending turned around.
void VisitRoom(WalkingPath* path) {
  path->Walk(7.5).Turn(M_PI / 2).Turn(-M_PI).Turn(-M_PI / 2).Walk(7.5);
}

// The suite's mapping run: the mapping square in the centre room, then each of the four
// neighbouring rooms in turn, back at the start facing east.
WalkingPath SuiteTour(const GaitOptions& gait) {
  WalkingPath path = SquarePath(-1.0, -1.0, gait);
  // To the crossing (kSuiteLaneX, kSuiteLaneY), facing east.
  path.Walk(1.0 + kSuiteLaneX).Turn(M_PI / 2).Walk(1.0 + kSuiteLaneY).Turn(-M_PI / 2);
  VisitRoom(&path);  // East; back facing west.
  VisitRoom(&path);  // West; back facing east.
  path.Turn(M_PI / 2);
  VisitRoom(&path);  // North; back facing south.
  VisitRoom(&path);  // South; back facing north.
  path.Turn(M_PI).Walk(1.0 + kSuiteLaneY).Turn(M_PI / 2);
  return path;
}

// Looks around where the robot stands: left, right and back to its heading.
void LookAround(WalkingPath* path) { path->Turn(M_PI / 2).Turn(-M_PI).Turn(M_PI / 2); }

// One round of the building from the centre room's lane crossing, facing east: to the east
// room, then round the eight outer rooms (counter-clockwise with `turn` = +pi/2, clockwise with
// -pi/2), looking around at each room's crossing, back through the east room to the centre, and
// turned to face east again, looking around there.
void BuildingRound(double turn, WalkingPath* path) {
  const double step_m = 8.0 + kSuiteWallM;  // From one room's lane crossing to the next.
  path->Walk(step_m);                       // East room.
  LookAround(path);
  path->Turn(turn);
  for (const int rooms : {1, 2, 2, 2}) {  // Along the ring's four sides: corner, middle, corner.
    for (int r = 0; r < rooms; ++r) {
      path->Walk(step_m);
      LookAround(path);
    }
    path->Turn(turn);
  }
  path->Walk(step_m);  // Back in the east room, facing the centre.
  path->Turn(turn);
  path->Walk(step_m);
  path->Turn(M_PI);
  LookAround(path);  // The centre room again.
}

// The building's mapping run: the mapping square, then three rounds of the eight rooms around
// the centre one (the second clockwise), each ending where the first began: every room is seen
// three times, from both sides, and every round closes a loop.
WalkingPath BuildingTour(const GaitOptions& gait) {
  WalkingPath path = SquarePath(-1.0, -1.0, gait);
  path.Walk(1.0 + kSuiteLaneX).Turn(M_PI / 2).Walk(1.0 + kSuiteLaneY).Turn(-M_PI / 2);
  BuildingRound(M_PI / 2, &path);
  BuildingRound(-M_PI / 2, &path);
  BuildingRound(M_PI / 2, &path);
  return path;
}

}  // namespace

SequenceSpec MakeSequenceSpec(const std::string& name, uint64_t seed) {
  const GaitOptions gait;
  SequenceSpec spec{name, "", RoomOptions{}, WalkingPath({}, gait), SensorModel{}, {}, {}};
  spec.room.seed = seed;
  if (name == "map_square") {
    spec.description = "mapping run: 2 m square loop, back to the start";
    spec.path = SquarePath(-1.0, -1.0, gait);
  } else if (name == "query_square") {
    spec.description = "2 m square offset by (0.3, 0.2) m from the mapping square";
    spec.path = SquarePath(-0.7, -0.8, gait);
  } else if (name == "blankwall") {
    spec.description =
        "the offset square; for 2.5 s the front pair faces a blank wall (no texture in view)";
    spec.path = SquarePath(-0.7, -0.8, gait);
    spec.blank_s.emplace_back(3.0, 5.5);
  } else if (name == "straight") {
    spec.description = "3 m straight line; the last metre leaves the mapped area";
    spec.path = WalkingPath({-1.0, 0.0, 0.0}, gait);
    spec.path.Walk(3.0);
  } else if (name == "circle") {
    spec.description = "3 m diameter circle: viewing directions the map never saw";
    spec.path = WalkingPath({0.0, -1.5, 0.0}, gait);
    spec.path.Arc(1.5, 2 * M_PI);
  } else if (name == "outward") {
    spec.description = "0.8 m circle inside the mapped square, facing out: views the map never had";
    GaitOptions facing_out = gait;
    facing_out.head_yaw_rad = -M_PI / 2;  // Walking counter-clockwise, the outside is right.
    spec.path = WalkingPath({0.0, -0.8, 0.0}, facing_out);
    spec.path.Arc(0.8, 2 * M_PI);
  } else if (name == "glances") {
    spec.description = "offset square, glancing 110 deg over the left shoulder every 6 s";
    GaitOptions glancing = gait;
    glancing.glance_yaw_rad = 110.0 * M_PI / 180.0;
    glancing.glance_period_s = 6.0;
    glancing.glance_s = 2.5;
    spec.path = SquarePath(-0.7, -0.8, glancing);
  } else if (name == "kidnap") {
    spec.description = "walks, camera covered ~1.2 s while carried 1.4 m left, walks on";
    spec.path = WalkingPath({-1.0, -1.0, 0.0}, gait);
    spec.path.Walk(1.2)
        .Stand(0.3)
        .Carry(0.0, 1.4, 0.0, 1.0)
        .Stand(0.3)
        .Walk(1.0)
        .Turn(M_PI / 2)
        .Walk(1.0);
    const auto carried = spec.path.CarriedIntervals().front();
    spec.covered_s.emplace_back(carried.first - 0.1, carried.second + 0.1);
  } else if (name == "lowlight") {
    spec.description = "offset square in low light: darker, gamma-changed, noisier";
    spec.path = SquarePath(-0.7, -0.8, gait);
    spec.sensor.exposure = 0.3;
    spec.sensor.gamma = 1.6;
    spec.sensor.read_noise_dn = 2.0;
  } else if (name == "occluders") {
    spec.description = "offset square while people cross the room";
    spec.path = SquarePath(-0.7, -0.8, gait);
    spec.room.people = true;
  } else if (name == "changed") {
    spec.description = "offset square after the boxes were moved";
    spec.path = SquarePath(-0.7, -0.8, gait);
    spec.room.layout = RoomOptions::Layout::kBoxesMoved;
  } else if (name == "outofmap") {
    spec.description = "a different room: nothing here is in the map";
    spec.room.seed = seed + 1000;
    spec.room.layout = RoomOptions::Layout::kRandom;
    spec.room.width_m = 6.5;
    spec.room.depth_m = 10.0;
    spec.room.height_m = 2.7;
    spec.path = WalkingPath({0.0, -1.0, M_PI / 2}, gait);
    spec.path.Walk(2.0).Turn(-M_PI / 2).Walk(1.0);
  } else if (name == "map_suite") {
    spec.description = "mapping run in the five-room suite: the square, then every room";
    spec.room.suite = true;
    spec.path = SuiteTour(gait);
  } else if (name == "map_building") {
    spec.description =
        "mapping run through a nine-room building: the square, then three rounds of its rooms";
    spec.room.building = true;
    spec.path = BuildingTour(gait);
  } else if (name == "query_suite") {
    spec.description = "the offset square in the suite's centre room, walls hiding 4 rooms";
    spec.room.suite = true;
    spec.path = SquarePath(-0.7, -0.8, gait);
  } else if (name == "drive") {
    spec.description = "outdoors, KITTI's rig and depths: a car drives a 51 m curve at 1 m a frame";
    spec.room.street = true;
    spec.car = true;
    GaitOptions car;  // Smooth: no steps, the camera 1.65 m above the road as on KITTI's car.
    car.speed_mps = 10.0;
    car.ramp_s = 0.02;  // At speed from the first frame, as KITTI's car.
    car.camera_height_m = 1.65;
    car.bob_amplitude_m = car.sway_amplitude_m = 0.0;
    car.roll_amplitude_deg = car.pitch_amplitude_deg = 0.0;
    spec.path = WalkingPath({0.0, 0.0, 0.0}, car);
    spec.path.Arc(kStreetRadiusM, kStreetAngleRad);
  } else {
    std::string known;
    for (const std::string& n : SequenceNames()) known += (known.empty() ? "" : ", ") + n;
    for (const std::string& n : LongSequenceNames()) known += ", " + n;
    throw InputError("unknown sequence '" + name + "' (known: " + known + ")");
  }
  return spec;
}

StereoShot RenderStereoShot(const World& world, const StereoRig& rig,
                            const Rigid3d& world_from_body, const SensorModel& sensor, Rng* noise,
                            int supersample) {
  const Renderer left_renderer(rig.left.camera, supersample);
  const Renderer right_renderer(rig.right.camera, supersample);
  StereoShot shot;
  shot.left =
      sensor.Capture(left_renderer.RenderRadiance(world, world_from_body * rig.left.body_from_cam,
                                                  0, &shot.left_depth),
                     noise);
  shot.right = sensor.Capture(
      right_renderer.RenderRadiance(world, world_from_body * rig.right.body_from_cam, 0), noise);
  return shot;
}

Rigid3d WorldFromMap(const RigOptions& rig) {
  const SequenceSpec map = MakeSequenceSpec("map_square", 1);
  return map.path.WorldFromBody(0.0) * MakeRig(rig).left.body_from_cam;
}

}  // namespace visloc::sim
