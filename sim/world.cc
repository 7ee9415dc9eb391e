#include "sim/world.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

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

// One room of the world, in world coordinates.
struct RoomPlan {
  Eigen::Vector2d centre_xy = Eigen::Vector2d::Zero();
  double width_m = 8.0, depth_m = 8.0, height_m = 3.0, texel_m = 0.004;
  uint64_t seed = 1;                         // Textures.
  bool plain_stretch = false;                // The low-texture stretch on the north wall.
  std::vector<Box> boxes;                    // Centres in world coordinates.
  std::vector<Eigen::Vector2d> doorways_xy;  // Doorway centres on the walls' inner faces.
  bool door_reveals = false;  // Close each doorway's passage through the wall thickness.
};

RoomPlan PlanRoom(const RoomOptions& options, const Eigen::Vector2d& centre_xy, uint64_t seed) {
  RoomPlan plan;
  plan.centre_xy = centre_xy;
  plan.width_m = options.width_m;
  plan.depth_m = options.depth_m;
  plan.height_m = options.height_m;
  plan.texel_m = options.texel_m;
  plan.seed = seed;
  return plan;
}

constexpr double kDoorWidthM = 1.0;
constexpr double kDoorHeightM = 2.1;

// A wall seen from inside its room: u runs left to right as seen from the room, v downwards;
// its Normal() points out of the room.
struct WallSpec {
  Eigen::Vector3d top_left;
  Eigen::Vector3d u_axis;
  double length;
};

// Where along the wall (metres from its left end) a doorway of `plan` is centred, if any.
std::optional<double> DoorwayAlong(const WallSpec& wall, const RoomPlan& plan) {
  for (const Eigen::Vector2d& door : plan.doorways_xy) {
    const Eigen::Vector2d offset = door - wall.top_left.head<2>();
    const double along = offset.dot(wall.u_axis.head<2>());
    const double across = (offset - along * wall.u_axis.head<2>()).norm();
    if (across > 1e-6 || along < 0 || along > wall.length) continue;
    VISLOC_CHECK(along >= kDoorWidthM && along <= wall.length - kDoorWidthM, "a doorway ", along,
                 " m along a ", wall.length, " m wall leaves no wall beside it");
    return along;
  }
  return std::nullopt;
}

// The wall with a doorway: the pieces left and right of it and the lintel above, each textured
// with its part of the one wall texture so the wall reads as one painted surface.
void AppendWallWithDoorway(const WallSpec& wall, double height_m, const cv::Mat& albedo,
                           double texel_m, double door_centre_m, World* world) {
  const Eigen::Vector3d down = -Eigen::Vector3d::UnitZ();
  const double u0 = door_centre_m - kDoorWidthM / 2, u1 = door_centre_m + kDoorWidthM / 2;
  const double lintel_m = height_m - kDoorHeightM;
  const auto columns = [&](double a, double b) {
    return cv::Range(static_cast<int>(std::lround(a / texel_m)),
                     static_cast<int>(std::lround(b / texel_m)));
  };
  const auto piece = [&](double u_start, double u_end, double v_end) {
    const cv::Mat part = albedo(cv::Range(0, static_cast<int>(std::lround(v_end / texel_m))),
                                columns(u_start, u_end))
                             .clone();
    const int texture = AddTexture(world, part, texel_m);
    world->surfaces.push_back(MakeSurface(wall.top_left + u_start * wall.u_axis, wall.u_axis, down,
                                          u_end - u_start, v_end, texture));
  };
  piece(0.0, u0, height_m);
  piece(u1, wall.length, height_m);
  piece(u0, u1, lintel_m);
}

// The doorway's passage through the wall: two jambs, the soffit and the threshold.
void AppendDoorReveals(const WallSpec& wall, double height_m, double door_centre_m, int texture,
                       World* world) {
  const Eigen::Vector3d down = -Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d out = wall.u_axis.cross(down);
  const double u0 = door_centre_m - kDoorWidthM / 2;
  const Eigen::Vector3d door_top_left =
      wall.top_left + u0 * wall.u_axis + (height_m - kDoorHeightM) * down;
  for (double u : {0.0, kDoorWidthM}) {
    world->surfaces.push_back(MakeSurface(door_top_left + u * wall.u_axis, out, down, kSuiteWallM,
                                          kDoorHeightM, texture));
  }
  world->surfaces.push_back(
      MakeSurface(door_top_left, wall.u_axis, out, kDoorWidthM, kSuiteWallM, texture));
  world->surfaces.push_back(MakeSurface(door_top_left + kDoorHeightM * down, wall.u_axis, out,
                                        kDoorWidthM, kSuiteWallM, texture));
}

void AppendRoom(const RoomPlan& plan, World* world) {
  const double w = plan.width_m, d = plan.depth_m, h = plan.height_m;
  const double texel = plan.texel_m;
  const uint64_t seed = plan.seed;
  const Eigen::Vector3d x = Eigen::Vector3d::UnitX(), y = Eigen::Vector3d::UnitY();
  const Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d c(plan.centre_xy.x(), plan.centre_xy.y(), 0.0);
  const WallSpec walls[4] = {
      {c + Eigen::Vector3d(-w / 2, d / 2, h), x, w},   // north wall (y = +d/2), seen facing +y
      {c + Eigen::Vector3d(w / 2, d / 2, h), -y, d},   // east wall (x = +w/2)
      {c + Eigen::Vector3d(w / 2, -d / 2, h), -x, w},  // south wall
      {c + Eigen::Vector3d(-w / 2, -d / 2, h), y, d},  // west wall
  };
  int reveal_texture = -1;
  for (int i = 0; i < 4; ++i) {
    cv::Mat albedo =
        GenerateTexture(TextureStyle::kPosterWall, walls[i].length, h, texel, seed * 10 + i);
    if (i == 0 && plan.plain_stretch) {
      // The low-texture stretch: 3 m of freshly painted wall, floor to ceiling.
      PaintPlain(&albedo, texel, 0.3 * w - 0.5, 0.3 * w + 2.5, 0.0, h, seed * 10 + 9);
    }
    const std::optional<double> door = DoorwayAlong(walls[i], plan);
    if (!door) {
      const int texture = AddTexture(world, albedo, texel);
      world->surfaces.push_back(
          MakeSurface(walls[i].top_left, walls[i].u_axis, -up, walls[i].length, h, texture));
      continue;
    }
    AppendWallWithDoorway(walls[i], h, albedo, texel, *door, world);
    if (plan.door_reveals) {
      if (reveal_texture < 0) {
        reveal_texture = AddTexture(
            world,
            GenerateTexture(TextureStyle::kPlain, kDoorWidthM, kDoorHeightM, texel, seed * 10 + 8),
            texel);
      }
      AppendDoorReveals(walls[i], h, *door, reveal_texture, world);
    }
  }
  const int floor = AddTexture(
      world, GenerateTexture(TextureStyle::kFloor, w, d, texel * 1.5, seed * 10 + 5), texel * 1.5);
  world->surfaces.push_back(MakeSurface(c + Eigen::Vector3d(-w / 2, -d / 2, 0), x, y, w, d, floor));
  const int ceiling = AddTexture(
      world, GenerateTexture(TextureStyle::kCeiling, w, d, texel * 2, seed * 10 + 6), texel * 2);
  world->surfaces.push_back(
      MakeSurface(c + Eigen::Vector3d(-w / 2, d / 2, h), x, -y, w, d, ceiling));
  for (size_t i = 0; i < plan.boxes.size(); ++i) {
    // Texture each box once, 1.5 m square, shared by its faces.
    Box box = plan.boxes[i];
    box.texture = AddTexture(
        world, GenerateTexture(TextureStyle::kBox, 1.5, 1.5, texel, seed * 100 + i), texel);
    AppendBoxFaces(box, &world->surfaces);
  }
}

// Up to 7 boxes at random in `plan`'s room, centres 0.5 m inside its walls, each kept where
// `allowed(box)`. Every draw is a statement of its own, so the layout does not depend on the
// compiler's order of evaluating arguments.
template <typename Allowed>
std::vector<Box> RandomBoxes(const RoomPlan& plan, Rng& rng, Allowed allowed) {
  std::vector<Box> boxes;
  const double half_w = plan.width_m / 2 - 0.5, half_d = plan.depth_m / 2 - 0.5;
  for (int attempt = 0; attempt < 300 && boxes.size() < 7; ++attempt) {
    const double y = rng.Uniform(-half_d, half_d);
    const double x = rng.Uniform(-half_w, half_w);
    const double height = rng.Uniform(0.4, 1.5);
    const double size_y = rng.Uniform(0.4, 1.0);
    const double size_x = rng.Uniform(0.4, 1.0);
    const Box box{plan.centre_xy + Eigen::Vector2d(x, y), Eigen::Vector3d(size_x, size_y, height),
                  0};
    if (allowed(box)) boxes.push_back(box);
  }
  return boxes;
}

// A box of a neighbouring room is kept out of the walking lanes through the doorways.
bool ClearOfSuiteLanes(const Box& box) {
  return std::abs(box.center_xy.x() - kSuiteLaneX) >= 1.5 + box.size_m.x() / 2 &&
         std::abs(box.center_xy.y() - kSuiteLaneY) >= 1.5 + box.size_m.y() / 2;
}

// The suite's rooms north, east, south and west of the centre room, each with its own
// textures and a doorway in the wall it shares with the centre room.
void AppendNeighbours(const RoomOptions& options, World* world) {
  const double w = options.width_m, d = options.depth_m, t = kSuiteWallM;
  const Eigen::Vector2d centres[4] = {{0, d + t}, {w + t, 0}, {0, -(d + t)}, {-(w + t), 0}};
  const Eigen::Vector2d doorways[4] = {{kSuiteLaneX, d / 2 + t},
                                       {w / 2 + t, kSuiteLaneY},
                                       {kSuiteLaneX, -(d / 2 + t)},
                                       {-(w / 2 + t), kSuiteLaneY}};
  for (int k = 0; k < 4; ++k) {
    const uint64_t seed = options.seed * 100003 + 11 * (k + 1);
    RoomPlan room = PlanRoom(options, centres[k], seed);
    Rng rng(seed * 7919 + 17);
    room.boxes = RandomBoxes(room, rng, ClearOfSuiteLanes);
    room.doorways_xy = {doorways[k]};
    AppendRoom(room, world);
  }
}

// The building's eight rooms around the centre one (RoomOptions::building): room (i, j) of the
// grid, i east and j north in -1..1, has a doorway on its lanes in every wall it shares with a
// neighbour. Of two rooms sharing a wall, the one with i + j even (the centre and the corners)
// closes the passage through the wall (its reveals), as the centre room does in the suite.
void AppendBuilding(const RoomOptions& options, World* world) {
  const double w = options.width_m, d = options.depth_m, t = kSuiteWallM;
  int k = 0;
  for (int j = -1; j <= 1; ++j) {
    for (int i = -1; i <= 1; ++i) {
      if (i == 0 && j == 0) continue;
      const Eigen::Vector2d centre(i * (w + t), j * (d + t));
      const uint64_t seed = options.seed * 100019 + 13 * (++k);
      RoomPlan room = PlanRoom(options, centre, seed);
      const Eigen::Vector2d lanes(centre.x() + kSuiteLaneX, centre.y() + kSuiteLaneY);
      Rng rng(seed * 7919 + 17);
      room.boxes = RandomBoxes(room, rng, [&](const Box& box) {
        return std::abs(box.center_xy.x() - lanes.x()) >= 1.5 + box.size_m.x() / 2 &&
               std::abs(box.center_xy.y() - lanes.y()) >= 1.5 + box.size_m.y() / 2;
      });
      if (j < 1) room.doorways_xy.emplace_back(lanes.x(), centre.y() + d / 2);
      if (i < 1) room.doorways_xy.emplace_back(centre.x() + w / 2, lanes.y());
      if (j > -1) room.doorways_xy.emplace_back(lanes.x(), centre.y() - d / 2);
      if (i > -1) room.doorways_xy.emplace_back(centre.x() - w / 2, lanes.y());
      room.door_reveals = (i + j) % 2 == 0;
      AppendRoom(room, world);
    }
  }
}

// People cross the room on lines outside the 2 m mapping square, at walking pace.
void AppendPeople(uint64_t seed, double texel_m, World* world) {
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
        world, GenerateTexture(TextureStyle::kPerson, 1.2, 1.75, texel_m, seed * 1000 + i),
        texel_m);
    mover.start_xy = paths[i].a;
    mover.end_xy = paths[i].b;
    mover.speed_mps = 0.9;
    mover.phase_s = paths[i].phase;
    world->movers.push_back(mover);
  }
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

World MakeStreet(const RoomOptions& options) {
  World world;
  world.width_m = 200.0;
  world.depth_m = 200.0;
  world.height_m = 20.0;
  Rng rng(options.seed * 104729 + 7);
  // Facades at a texel of 2 cm: corners from 10 cm up, which a 720 px focal length resolves
  // to beyond 50 m. Several textures, so neighbouring buildings do not repeat one another.
  constexpr double kFacadeTexelM = 0.02;
  constexpr int kFacades = 8;
  std::vector<int> facades;
  for (int i = 0; i < kFacades; ++i) {
    facades.push_back(AddTexture(&world,
                                 GenerateTexture(TextureStyle::kPosterWall, 20.0, 16.0,
                                                 kFacadeTexelM, options.seed * 100 + i),
                                 kFacadeTexelM));
  }
  // The road and the land around it.
  constexpr double kGroundTexelM = 0.02;
  const int ground = AddTexture(
      &world,
      GenerateTexture(TextureStyle::kFloor, 60.0, 60.0, kGroundTexelM, options.seed * 100 + 50),
      kGroundTexelM);
  for (int gx = -1; gx < 3; ++gx) {
    for (int gy = -1; gy < 2; ++gy) {
      world.surfaces.push_back(MakeSurface(Eigen::Vector3d(gx * 60.0 - 20.0, gy * 60.0 - 10.0, 0),
                                           Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY(), 60.0,
                                           60.0, ground));
    }
  }
  // Where the arc is at angle theta, and its outward normal (to the right of the car).
  const Eigen::Vector2d centre(0.0, kStreetRadiusM);
  const auto on_arc = [&](double theta, double right_m) {
    const Eigen::Vector2d outward(std::sin(theta), -std::cos(theta));
    return Eigen::Vector2d(centre + (kStreetRadiusM + right_m) * outward);
  };
  const auto building = [&](const Eigen::Vector2d& xy, double size_m, double height_m) {
    Box box{xy, {size_m, size_m, height_m}, facades[rng.UniformInt(0, kFacades - 1)]};
    AppendBoxFaces(box, &world.surfaces);
  };
  // Rows along the road, a building every 5-9 m, from a little behind the start to past the end.
  for (const double side : {-1.0, 1.0}) {
    for (const auto& [near_m, far_m] : {std::pair{6.0, 12.0}, std::pair{20.0, 30.0}}) {
      for (double along_m = -10.0; along_m < kStreetRadiusM * kStreetAngleRad + 30.0;) {
        const double size_m = rng.Uniform(3.0, 6.0);
        const double offset_m = rng.Uniform(near_m, far_m) + size_m / 2;
        building(on_arc(along_m / kStreetRadiusM, side * offset_m), size_m, rng.Uniform(4.0, 14.0));
        along_m += size_m + rng.Uniform(2.0, 4.0);
      }
    }
  }
  // Large buildings far ahead of the start and of the end.
  for (const double theta : {0.0, kStreetAngleRad}) {
    const Eigen::Vector2d start = on_arc(theta, 0.0);
    const Eigen::Vector2d ahead(std::cos(theta), std::sin(theta));
    const Eigen::Vector2d left(-ahead.y(), ahead.x());
    for (int i = -2; i <= 2; ++i) {
      building(start + rng.Uniform(60.0, 100.0) * ahead + i * 25.0 * left, rng.Uniform(12.0, 18.0),
               rng.Uniform(10.0, 20.0));
    }
  }
  return world;
}

World MakeRoom(const RoomOptions& options) {
  VISLOC_CHECK(options.width_m > 4.6 && options.depth_m > 4.6 && options.height_m > 2.0, "room ",
               options.width_m, "x", options.depth_m, "x", options.height_m,
               " leaves no space to walk");
  VISLOC_CHECK(!((options.suite || options.building) && options.people),
               "the suite and the building have no people");
  VISLOC_CHECK(!(options.suite && options.building), "a world is the suite or the building");
  World world;
  world.width_m = options.width_m;
  world.depth_m = options.depth_m;
  world.height_m = options.height_m;
  Rng rng(options.seed * 7919 + 17);
  RoomPlan centre = PlanRoom(options, Eigen::Vector2d::Zero(), options.seed);
  centre.plain_stretch = true;
  switch (options.layout) {
    case RoomOptions::Layout::kReference:
      centre.boxes = ReferenceBoxes();
      break;
    case RoomOptions::Layout::kBoxesMoved:
      centre.boxes = MovedBoxes();
      break;
    case RoomOptions::Layout::kRandom:
      // Clear of the disc where the robot walks.
      centre.boxes =
          RandomBoxes(centre, rng, [](const Box& b) { return b.center_xy.norm() >= 2.8; });
      break;
  }
  if (options.suite || options.building) {
    const double w = options.width_m, d = options.depth_m;
    centre.doorways_xy = {
        {kSuiteLaneX, d / 2}, {w / 2, kSuiteLaneY}, {kSuiteLaneX, -d / 2}, {-w / 2, kSuiteLaneY}};
    centre.door_reveals = true;
  }
  AppendRoom(centre, &world);
  if (options.suite) AppendNeighbours(options, &world);
  if (options.building) AppendBuilding(options, &world);
  if (options.people) AppendPeople(options.seed, options.texel_m, &world);
  return world;
}

}  // namespace visloc::sim
