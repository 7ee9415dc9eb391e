#include "sim/world.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/util/check.h"
#include "core/util/random.h"

namespace visloc::sim {

float ShadeForNormal(const Eigen::Vector3d& normal) {
  const Eigen::Vector3d light = Eigen::Vector3d(0.35, 0.2, 0.9).normalized();
  return static_cast<float>(0.6 + 0.4 * std::abs(normal.normalized().dot(light)));
}

Eigen::Vector2d Mover::PositionAt(double time_s) const {
  const double length = (end_xy - start_xy).norm();
  if (length <= 0 || speed_mps <= 0) return start_xy;
  const double period = 2.0 * length / speed_mps;
  double phase = std::fmod(time_s + phase_s, period);
  if (phase < 0) phase += period;
  const double travelled = phase * speed_mps;
  const double fraction = travelled <= length ? travelled / length : 2.0 - travelled / length;
  return start_xy + fraction * (end_xy - start_xy);
}

namespace {

Surface MakeSurface(const Eigen::Vector3d& origin, const Eigen::Vector3d& u_axis,
                    const Eigen::Vector3d& v_axis, double size_u, double size_v, int texture) {
  Surface surface;
  surface.origin = origin;
  surface.u_axis = u_axis;
  surface.v_axis = v_axis;
  surface.size_u_m = size_u;
  surface.size_v_m = size_v;
  surface.texture = texture;
  surface.shade = ShadeForNormal(u_axis.cross(v_axis));
  return surface;
}

int AddTexture(World* world, const cv::Mat& albedo, double texel_m) {
  world->textures.push_back(std::make_shared<const Texture>(albedo, texel_m));
  return static_cast<int>(world->textures.size()) - 1;
}

// Boxes are kept out of the disc of radius 2.3 m around the room centre where the robot walks.
std::vector<Box> ReferenceBoxes() {
  return {
      {{3.0, 2.7}, {0.8, 0.6, 1.0}, 0},   {{-3.1, 2.9}, {0.6, 0.6, 0.7}, 0},
      {{-3.2, -0.4}, {0.7, 1.0, 1.2}, 0}, {{2.9, -1.0}, {0.6, 0.8, 0.6}, 0},
      {{1.2, -3.3}, {1.0, 0.6, 0.9}, 0},  {{-1.6, -3.2}, {0.6, 0.6, 1.4}, 0},
      {{0.4, 3.3}, {0.8, 0.5, 0.5}, 0},   {{-2.7, -2.8}, {0.5, 0.5, 0.8}, 0},
  };
}

// The changed environment: two boxes pushed aside, one removed, one new.
std::vector<Box> MovedBoxes() {
  std::vector<Box> boxes = ReferenceBoxes();
  boxes[0].center_xy += Eigen::Vector2d(-0.5, 0.3);
  boxes[2].center_xy += Eigen::Vector2d(0.2, 0.8);
  boxes.erase(boxes.begin() + 4);
  boxes.push_back({{2.6, 1.0}, {0.6, 0.6, 0.9}, 0});
  return boxes;
}

std::vector<Box> RandomBoxes(const RoomOptions& options, Rng& rng) {
  std::vector<Box> boxes;
  const double half_w = options.width_m / 2 - 0.5, half_d = options.depth_m / 2 - 0.5;
  for (int attempt = 0; attempt < 200 && boxes.size() < 7; ++attempt) {
    const Eigen::Vector2d center(rng.Uniform(-half_w, half_w), rng.Uniform(-half_d, half_d));
    if (center.norm() < 2.8) continue;
    boxes.push_back(
        {center, {rng.Uniform(0.4, 1.0), rng.Uniform(0.4, 1.0), rng.Uniform(0.4, 1.5)}, 0});
  }
  return boxes;
}

}  // namespace

void AppendBoxFaces(const Box& box, std::vector<Surface>* surfaces) {
  const Eigen::Vector3d half(box.size_m.x() / 2, box.size_m.y() / 2, 0);
  const Eigen::Vector3d corner(box.center_xy.x() - half.x(), box.center_xy.y() - half.y(), 0);
  const double sx = box.size_m.x(), sy = box.size_m.y(), sz = box.size_m.z();
  const Eigen::Vector3d x = Eigen::Vector3d::UnitX(), y = Eigen::Vector3d::UnitY();
  const Eigen::Vector3d down = -Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d top(0, 0, sz);
  // Side faces run from the top edge downwards so texture rows read top to bottom. Rendering
  // is two-sided and shading uses |n . light|, so the sign of u x v does not matter.
  surfaces->push_back(MakeSurface(corner + top, x, down, sx, sz, box.texture));  // -y
  surfaces->push_back(
      MakeSurface(corner + top + Eigen::Vector3d(sx, sy, 0), -x, down, sx, sz, box.texture));  // +y
  surfaces->push_back(
      MakeSurface(corner + top + Eigen::Vector3d(0, sy, 0), -y, down, sy, sz, box.texture));  // -x
  surfaces->push_back(
      MakeSurface(corner + top + Eigen::Vector3d(sx, 0, 0), y, down, sy, sz, box.texture));  // +x
  surfaces->push_back(MakeSurface(corner + top, x, y, sx, sy, box.texture));                 // top
}

double DistanceToNearestSurface(const World& world, const Eigen::Vector3d& point_in_world) {
  double nearest = std::numeric_limits<double>::infinity();
  for (const Surface& s : world.surfaces) {
    const Eigen::Vector3d offset = point_in_world - s.origin;
    const double a = std::clamp(offset.dot(s.u_axis), 0.0, s.size_u_m);
    const double b = std::clamp(offset.dot(s.v_axis), 0.0, s.size_v_m);
    nearest = std::min(nearest, (point_in_world - s.PointAt(a, b)).norm());
  }
  return nearest;
}

std::vector<Surface> World::SurfacesAt(double time_s) const {
  std::vector<Surface> result = surfaces;
  for (const Mover& mover : movers) {
    Box box = mover.box;
    box.center_xy = mover.PositionAt(time_s);
    AppendBoxFaces(box, &result);
  }
  return result;
}

World MakeRoom(const RoomOptions& options) {
  VISLOC_CHECK(options.width_m > 4.6 && options.depth_m > 4.6 && options.height_m > 2.0, "room ",
               options.width_m, "x", options.depth_m, "x", options.height_m,
               " leaves no space to walk");
  World world;
  world.width_m = options.width_m;
  world.depth_m = options.depth_m;
  world.height_m = options.height_m;
  const double w = options.width_m, d = options.depth_m, h = options.height_m;
  const double texel = options.texel_m;
  const uint64_t seed = options.seed;
  Rng rng(seed * 7919 + 17);
  const Eigen::Vector3d x = Eigen::Vector3d::UnitX(), y = Eigen::Vector3d::UnitY();
  const Eigen::Vector3d up = Eigen::Vector3d::UnitZ();

  // Walls, each seen from inside: u runs left to right as seen from the room, v downwards.
  struct WallSpec {
    Eigen::Vector3d top_left;
    Eigen::Vector3d u_axis;
    double length;
  };
  const WallSpec walls[4] = {
      {{-w / 2, d / 2, h}, x, w},   // north wall (y = +d/2), seen facing +y
      {{w / 2, d / 2, h}, -y, d},   // east wall (x = +w/2)
      {{w / 2, -d / 2, h}, -x, w},  // south wall
      {{-w / 2, -d / 2, h}, y, d},  // west wall
  };
  for (int i = 0; i < 4; ++i) {
    cv::Mat albedo =
        GenerateTexture(TextureStyle::kPosterWall, walls[i].length, h, texel, seed * 10 + i);
    if (i == 0) {
      // The low-texture stretch: 3 m of freshly painted wall, floor to ceiling.
      PaintPlain(&albedo, texel, 0.3 * w - 0.5, 0.3 * w + 2.5, 0.0, h, seed * 10 + 9);
    }
    const int texture = AddTexture(&world, albedo, texel);
    world.surfaces.push_back(
        MakeSurface(walls[i].top_left, walls[i].u_axis, -up, walls[i].length, h, texture));
  }
  const int floor = AddTexture(
      &world, GenerateTexture(TextureStyle::kFloor, w, d, texel * 1.5, seed * 10 + 5), texel * 1.5);
  world.surfaces.push_back(MakeSurface({-w / 2, -d / 2, 0}, x, y, w, d, floor));
  const int ceiling = AddTexture(
      &world, GenerateTexture(TextureStyle::kCeiling, w, d, texel * 2, seed * 10 + 6), texel * 2);
  world.surfaces.push_back(MakeSurface({-w / 2, d / 2, h}, x, -y, w, d, ceiling));

  std::vector<Box> boxes;
  switch (options.layout) {
    case RoomOptions::Layout::kReference:
      boxes = ReferenceBoxes();
      break;
    case RoomOptions::Layout::kBoxesMoved:
      boxes = MovedBoxes();
      break;
    case RoomOptions::Layout::kRandom:
      boxes = RandomBoxes(options, rng);
      break;
  }
  for (size_t i = 0; i < boxes.size(); ++i) {
    // Texture each box once, 1 m square, shared by its faces.
    boxes[i].texture = AddTexture(
        &world, GenerateTexture(TextureStyle::kBox, 1.5, 1.5, texel, seed * 100 + i), texel);
    AppendBoxFaces(boxes[i], &world.surfaces);
  }
  if (options.people) {
    // People cross the room on lines outside the 2 m mapping square, at walking pace.
    const struct {
      Eigen::Vector2d a, b;
      double phase;
    } paths[] = {
        {{2.0, -3.0}, {2.0, 3.0}, 0.0},
        {{-3.0, 2.0}, {3.0, 2.0}, 2.5},
        {{-2.0, 3.0}, {-2.0, -3.0}, 5.0},
        {{3.0, -2.0}, {-3.0, -2.0}, 1.2},
    };
    for (int i = 0; i < 4; ++i) {
      Mover mover;
      mover.box = {paths[i].a, {0.45, 0.3, 1.75}, 0};
      mover.box.texture = AddTexture(
          &world, GenerateTexture(TextureStyle::kPerson, 1.2, 1.75, texel, seed * 1000 + i), texel);
      mover.start_xy = paths[i].a;
      mover.end_xy = paths[i].b;
      mover.speed_mps = 0.9;
      mover.phase_s = paths[i].phase;
      world.movers.push_back(mover);
    }
  }
  return world;
}

}  // namespace visloc::sim
