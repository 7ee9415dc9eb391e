#include "sim/board_views.h"

#include <cmath>
#include <cstdio>
#include <filesystem>

#include "core/image/image_codec.h"
#include "core/util/check.h"
#include "core/util/random.h"
#include "core/util/strings.h"
#include "dataset/euroc.h"
#include "sim/renderer.h"

namespace visloc::sim {
namespace fs = std::filesystem;

void BoardViewOptions::Check() const {
  VISLOC_CHECK(cols >= 3 && rows >= 3 && square_m > 0 && views >= 1 && supersample >= 1,
               "board views: ", cols, "x", rows, ", ", square_m, " m, ", views, " views");
}

namespace {

constexpr int kTexelsPerSquare = 24;

// The board: (cols + 1) x (rows + 1) squares, black in the top-left corner, inside a white
// margin of one square, on the plane of a Surface whose u axis runs along the rows.
void WriteView(const std::string& path, const cv::Mat& image) {
  std::string why;
  if (!image::WritePng(path, image, 1, &why)) throw InputError(why);
}

std::shared_ptr<const Texture> BoardTexture(const BoardViewOptions& o) {
  const int squares_u = o.cols + 3, squares_v = o.rows + 3;  // With the margin.
  cv::Mat albedo(squares_v * kTexelsPerSquare, squares_u * kTexelsPerSquare, CV_8UC1,
                 cv::Scalar(235));
  for (int r = 0; r <= o.rows; ++r) {
    for (int c = 0; c <= o.cols; ++c) {
      if ((r + c) % 2) continue;
      albedo(cv::Rect((c + 1) * kTexelsPerSquare, (r + 1) * kTexelsPerSquare, kTexelsPerSquare,
                      kTexelsPerSquare))
          .setTo(cv::Scalar(20));
    }
  }
  return std::make_shared<Texture>(albedo, o.square_m / kTexelsPerSquare);
}

// A plain room around the rig, 6 m on a side, and the board.
World BoardWorld(const BoardViewOptions& o) {
  World world;
  world.textures.push_back(BoardTexture(o));
  cv::Mat plain(64, 64, CV_8UC1, cv::Scalar(140));
  world.textures.push_back(std::make_shared<Texture>(plain, 0.1));
  const double h = 3.0;
  const Eigen::Vector3d x = Eigen::Vector3d::UnitX(), y = Eigen::Vector3d::UnitY(),
                        z = Eigen::Vector3d::UnitZ();
  // Faces of the cube [-h, h]^3, each seen from inside.
  const std::pair<Eigen::Vector3d, std::pair<Eigen::Vector3d, Eigen::Vector3d>> faces[6] = {
      {-h * x, {y, z}}, {h * x, {z, y}}, {-h * y, {z, x}},
      {h * y, {x, z}},  {-h * z, {x, y}}, {h * z, {y, x}}};
  for (const auto& [centre, axes] : faces) {
    Surface s;
    s.u_axis = axes.first;
    s.v_axis = axes.second;
    s.origin = centre - h * (axes.first + axes.second);
    s.size_u_m = s.size_v_m = 2 * h;
    s.texture = 1;
    s.shade = 0.8f;
    world.surfaces.push_back(s);
  }
  return world;
}

// The board's corners (with the margin) in the board surface frame, for the visibility test.
std::array<Eigen::Vector3d, 4> Outline(const BoardViewOptions& o) {
  const double u = (o.cols + 3) * o.square_m, v = (o.rows + 3) * o.square_m;
  return {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(u, 0, 0), Eigen::Vector3d(u, v, 0),
          Eigen::Vector3d(0, v, 0)};
}

bool WholeInView(const Camera& camera, const Rigid3d& cam_from_board,
                 const std::array<Eigen::Vector3d, 4>& outline) {
  for (const Eigen::Vector3d& corner : outline) {
    Eigen::Vector2d pixel;
    if (!camera.Project(cam_from_board * corner, &pixel) || !camera.IsInImage(pixel, 4.0)) {
      return false;
    }
  }
  return true;
}

}  // namespace

BoardViewStats GenerateBoardViews(const RigOptions& rig_options, const BoardViewOptions& o,
                                  const std::string& dir) {
  o.Check();
  const StereoRig rig = MakeRig(rig_options);
  const World world = BoardWorld(o);
  const auto outline = Outline(o);
  const Renderer left_renderer(rig.left.camera, o.supersample);
  const Renderer right_renderer(rig.right.camera, o.supersample);
  fs::create_directories(dir + "/left");
  fs::create_directories(dir + "/right");
  // The body is at the origin; cameras look along the body's x axis.
  const Rigid3d& world_from_left = rig.left.body_from_cam;
  const Rigid3d& world_from_right = rig.right.body_from_cam;
  const Camera& camera = rig.left.camera;
  const double board_m = std::hypot(o.cols + 3, o.rows + 3) * o.square_m;
  // Half the field of view across the diagonal, from the image corner's ray.
  const Eigen::Vector3d corner_ray = camera.Unproject(Eigen::Vector2d(0, 0));
  const double half_fov = std::atan(corner_ray.head<2>().norm());
  Rng rng(o.seed * 7919 + 17);
  SensorModel sensor;
  BoardViewStats stats;
  while (stats.views < o.views) {
    VISLOC_CHECK(++stats.attempts < 200 * o.views, "no board pose fits both images");
    // A direction within the field of view, the board at a distance where it spans 25 to 60 %
    // of the image diagonal's angle, facing the camera with a tilt and a turn.
    const double theta = half_fov * std::sqrt(rng.Uniform(0.0, 0.85));
    const double phi = rng.Uniform(-M_PI, M_PI);
    const Eigen::Vector3d direction(std::sin(theta) * std::cos(phi),
                                    std::sin(theta) * std::sin(phi), std::cos(theta));
    const double span = rng.Uniform(0.25, 0.6) * 2 * half_fov;
    const double distance = board_m / (2 * std::tan(0.5 * std::min(span, 2.5)));
    const Eigen::Quaterniond facing = Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(),
                                                                         direction);
    const Eigen::Quaterniond tilt =
        RotationFromRollPitchYaw(rng.Uniform(-0.6, 0.6), rng.Uniform(-0.6, 0.6),
                                 rng.Uniform(-0.35, 0.35));
    // The board's centre on the ray; its own frame: x along the rows, y down the columns,
    // z away from the camera (its back).
    const Eigen::Vector3d centre = distance * direction;
    const Eigen::Quaterniond left_from_board_rotation = facing * tilt;
    const Eigen::Vector3d half_size(0.5 * (o.cols + 3) * o.square_m,
                                    0.5 * (o.rows + 3) * o.square_m, 0);
    const Rigid3d left_from_board(left_from_board_rotation,
                                  centre - left_from_board_rotation * half_size);
    const Rigid3d right_from_board = rig.right.body_from_cam.Inverse() * world_from_left *
                                     left_from_board;
    if (!WholeInView(rig.left.camera, left_from_board, outline) ||
        !WholeInView(rig.right.camera, right_from_board, outline)) {
      continue;
    }
    World scene = world;
    const Rigid3d world_from_board = world_from_left * left_from_board;
    Surface board;
    board.origin = world_from_board.translation;
    board.u_axis = world_from_board.rotation * Eigen::Vector3d::UnitX();
    board.v_axis = world_from_board.rotation * Eigen::Vector3d::UnitY();
    board.size_u_m = (o.cols + 3) * o.square_m;
    board.size_v_m = (o.rows + 3) * o.square_m;
    board.texture = 0;
    scene.surfaces.push_back(board);
    Rng noise(o.seed * 1000 + stats.views);
    char name[32];
    std::snprintf(name, sizeof(name), "%03d.png", stats.views);
    WriteView(dir + "/left/" + name,
              sensor.Capture(left_renderer.RenderRadiance(scene, world_from_left, 0), &noise));
    WriteView(dir + "/right/" + name,
              sensor.Capture(right_renderer.RenderRadiance(scene, world_from_right, 0), &noise));
    ++stats.views;
  }
  // The truth, as calibrate writes it: the left camera is the body.
  CameraInfo left = rig.left, right = rig.right;
  left.body_from_cam = Rigid3d::Identity();
  right.body_from_cam = rig.left.body_from_cam.Inverse() * rig.right.body_from_cam;
  left.rate_hz = right.rate_hz = 0;
  fs::create_directories(dir + "/truth/cam0");
  fs::create_directories(dir + "/truth/cam1");
  WriteSensorYaml(dir + "/truth/cam0/sensor.yaml", left, "left camera (the truth)");
  WriteSensorYaml(dir + "/truth/cam1/sensor.yaml", right, "right camera (the truth)");
  return stats;
}

}  // namespace visloc::sim
