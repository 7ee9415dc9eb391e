#pragma once
// The synthetic world: textured planar rectangles (room walls, floor, ceiling, box faces) and
// box-shaped occluders that move on straight lines ("people").
//
// World frame: origin on the floor at the room's centre, z up, metres. The room spans
// x in [-width/2, width/2], y in [-depth/2, depth/2], z in [0, height]. In the suite (several
// rooms behind doorways) that room is the centre room; the others adjoin it.

#include <cstdint>
#include <memory>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "sim/texture.h"

namespace visloc::sim {

// A textured rectangle: the points origin + a * u_axis + b * v_axis for a in [0, size_u_m],
// b in [0, size_v_m]. Texture coordinates are (a, b) in metres. Axes are unit and orthogonal.
struct Surface {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  Eigen::Vector3d u_axis = Eigen::Vector3d::UnitX();
  Eigen::Vector3d v_axis = Eigen::Vector3d::UnitY();
  double size_u_m = 1.0;
  double size_v_m = 1.0;
  int texture = 0;     // Index into World::textures.
  float shade = 1.0f;  // Lighting factor in (0, 1]: radiance = albedo * shade.
  Eigen::Vector3d Normal() const { return u_axis.cross(v_axis); }
  Eigen::Vector3d PointAt(double a_m, double b_m) const {
    return origin + a_m * u_axis + b_m * v_axis;
  }
};

// An axis-aligned box standing on the floor.
struct Box {
  Eigen::Vector2d center_xy = Eigen::Vector2d::Zero();
  Eigen::Vector3d size_m = Eigen::Vector3d::Ones();  // x, y extent and height.
  int texture = 0;
};

// A box that walks back and forth between two floor points at constant speed.
struct Mover {
  Box box;
  Eigen::Vector2d start_xy = Eigen::Vector2d::Zero();
  Eigen::Vector2d end_xy = Eigen::Vector2d::Zero();
  double speed_mps = 1.0;
  double phase_s = 0.0;  // Time offset along its round trip.
  Eigen::Vector2d PositionAt(double time_s) const;
};

struct World {
  double width_m = 8.0;
  double depth_m = 8.0;
  double height_m = 3.0;
  std::vector<Surface> surfaces;  // Static geometry.
  std::vector<Mover> movers;
  std::vector<std::shared_ptr<const Texture>> textures;

  // Static surfaces plus the movers' faces at `time_s`.
  std::vector<Surface> SurfacesAt(double time_s) const;
};

struct RoomOptions {
  double width_m = 8.0;
  double depth_m = 8.0;
  double height_m = 3.0;
  double texel_m = 0.004;  // Texture resolution: finer than a 640x480 pixel at 1 m.
  uint64_t seed = 1;       // Textures and, for a random layout, the boxes.
  enum class Layout { kReference, kBoxesMoved, kRandom } layout = Layout::kReference;
  bool people = false;  // Add people walking across the room.
  // The suite: four more rooms of the same size adjoin the room to the north, east, south and
  // west, each behind a 0.1 m wall with a 1 m x 2.1 m doorway. Most of what a camera's frustum
  // holds is then hidden behind walls, as in a real building (seed paper 000, Sec. 5).
  bool suite = false;
  // The building: nine rooms of the same size in a 3 x 3 grid (the suite's five and the four
  // corners), each with a doorway in every wall it shares with a neighbour, on the suite's
  // lanes, which are kept free of boxes in every room. A run through all of them and back is
  // four times the suite's and more (issue 58: mapping a whole building in one run).
  bool building = false;
  // Outdoors instead of a room (MakeStreet): a road between buildings, seen from a car.
  bool street = false;
};

// The street's road: from the origin heading +x, an arc curving left of this radius through
// this angle (51 m), as a car drives it in the `drive` sequence.
inline constexpr double kStreetRadiusM = 60.0;
inline constexpr double kStreetAngleRad = 0.85;

// The walking lanes of the suite: the doorways are centred on the lines x = kSuiteLaneX (north
// and south walls) and y = kSuiteLaneY (east and west walls), and bands of +-1.5 m around these
// lines are kept free of boxes in the neighbouring rooms, so a path along them walks through.
inline constexpr double kSuiteLaneX = -0.5;
inline constexpr double kSuiteLaneY = 0.5;
inline constexpr double kSuiteWallM = 0.1;  // Wall thickness between rooms.

// The default room: rich poster walls with a plain, low-texture stretch on the north wall,
// tiled floor, panel ceiling, and boxes around the walking area (which is the disc of radius
// ~2.2 m around the centre, kept free for the robot). With `options.suite`, the room with its
// four neighbours (their own textures and randomly placed boxes, the lanes kept free).
World MakeRoom(const RoomOptions& options);

// A street seen from a car, with KITTI's depths: a textured road, rows of buildings 6-12 m and
// 20-30 m to either side of the arc above, 4-14 m tall, and large buildings 60-100 m ahead of
// its start and its end. Every surface is textured like a facade (shapes from 10 cm to 3 m).
World MakeStreet(const RoomOptions& options);

// Appends the 5 visible faces (4 sides and the top) of `box` to `surfaces`.
void AppendBoxFaces(const Box& box, std::vector<Surface>* surfaces);

// Distance (metres) from `point_in_world` to the nearest static surface: the true scene
// geometry that map points are checked against.
double DistanceToNearestSurface(const World& world, const Eigen::Vector3d& point_in_world);

// Lambertian shading with a fixed light from above: faces differ in brightness, so box edges
// stay visible where the albedo alone would not show them.
float ShadeForNormal(const Eigen::Vector3d& normal);

}  // namespace visloc::sim
