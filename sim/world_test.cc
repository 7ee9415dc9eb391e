#include "sim/world.h"

#include <gtest/gtest.h>

#include <set>

#include <opencv2/core.hpp>

#include "sim/renderer.h"
#include "sim/sequences.h"

namespace visloc::sim {
namespace {

// Coarse textures: these tests look at geometry, not appearance.
World MakeTestSuite() {
  RoomOptions options;
  options.texel_m = 0.02;
  options.suite = true;
  return MakeRoom(options);
}

// The left camera of a robot standing at (x, y) with heading `yaw`, level.
Rigid3d WorldFromCamera(double x, double y, double yaw) {
  const StereoRig rig = MakeRig(RigOptions{});
  const Rigid3d world_from_body(RotationFromRollPitchYaw(0.0, 0.0, yaw),
                                Eigen::Vector3d(x, y, 1.45));
  return world_from_body * rig.left.body_from_cam;
}

cv::Mat RenderDepth(const World& world, const Rigid3d& world_from_cam) {
  const Renderer renderer(MakeRig(RigOptions{}).left.camera, 1);
  cv::Mat depth;
  renderer.RenderRadiance(world, world_from_cam, 0.0, &depth);
  return depth;
}

TEST(SuiteTest, TheCentreRoomIsTheRoomWithDoorways) {
  RoomOptions options;
  options.texel_m = 0.02;
  const World room = MakeRoom(options);
  ASSERT_EQ(room.surfaces.size(), 4 + 2 + 8 * 5u);  // Walls, floor, ceiling, 8 boxes.
  const World suite = MakeTestSuite();
  // The centre room's walls come first, each in 3 pieces around its doorway plus the 4 faces
  // of the passage through the wall; then its floor, ceiling and boxes exactly as in the room.
  const size_t walls = 4 * (3 + 4);
  ASSERT_GT(suite.surfaces.size(), walls + room.surfaces.size() - 4);
  for (size_t i = 4; i < room.surfaces.size(); ++i) {
    const Surface& a = room.surfaces[i];
    const Surface& b = suite.surfaces[walls + i - 4];
    EXPECT_EQ(a.origin, b.origin) << i;
    EXPECT_EQ(a.u_axis, b.u_axis) << i;
    EXPECT_EQ(a.v_axis, b.v_axis) << i;
    EXPECT_EQ(a.size_u_m, b.size_u_m) << i;
  }
  // The wall pieces cover the wall but for the doorway: 8 m x 3 m less 1 m x 2.1 m.
  double wall_area_m2 = 0;
  for (size_t i = 0; i < walls; ++i) {
    const Surface& s = suite.surfaces[i];
    if (s.size_u_m > kSuiteWallM + 1e-9 && s.size_v_m > kSuiteWallM + 1e-9) {
      wall_area_m2 += s.size_u_m * s.size_v_m;
    }
  }
  EXPECT_NEAR(wall_area_m2, 4 * (8.0 * 3.0 - 1.0 * 2.1), 1e-9);
  // Four neighbours: 4 walls, one with its doorway (3 pieces), floor, ceiling, boxes each.
  EXPECT_GT(suite.surfaces.size(), walls + room.surfaces.size() - 4 + 4 * (6 + 2 + 5));
}

TEST(SuiteTest, WallsHideTheNeighbouringRooms) {
  const World suite = MakeTestSuite();
  // Facing each corner of the centre room from 1.5 m away along both walls, with no doorway
  // in view: nothing is seen beyond the corner, 1.5 * sqrt(2) m ahead in z-depth, although
  // two neighbouring rooms lie in the frustum behind the walls.
  for (double sx : {-1.0, 1.0}) {
    for (double sy : {-1.0, 1.0}) {
      const cv::Mat depth =
          RenderDepth(suite, WorldFromCamera(2.5 * sx, 2.5 * sy, std::atan2(sy, sx)));
      double farthest_m = 0;
      cv::minMaxLoc(depth, nullptr, &farthest_m);
      EXPECT_EQ(cv::countNonZero(depth > 0), depth.rows * depth.cols) << sx << ", " << sy;
      EXPECT_LT(farthest_m, 1.5 * std::sqrt(2.0) + 0.01) << sx << ", " << sy;
    }
  }
}

TEST(SuiteTest, EachDoorwayOpensIntoItsRoom) {
  const World suite = MakeTestSuite();
  // From the lanes' crossing, the image centre looks through each doorway at the far wall of
  // the neighbouring room: the lanes are free of boxes.
  const double w = suite.width_m, t = kSuiteWallM;
  const struct {
    double yaw, far_wall_m;
  } views[] = {{0.0, 1.5 * w + t - kSuiteLaneX},         // east: x = 12.1
               {M_PI, 1.5 * w + t + kSuiteLaneX},        // west: x = -12.1
               {M_PI / 2, 1.5 * w + t - kSuiteLaneY},    // north: y = 12.1
               {-M_PI / 2, 1.5 * w + t + kSuiteLaneY}};  // south: y = -12.1
  for (const auto& view : views) {
    const cv::Mat depth = RenderDepth(suite, WorldFromCamera(kSuiteLaneX, kSuiteLaneY, view.yaw));
    EXPECT_NEAR(depth.at<float>(depth.rows / 2, depth.cols / 2), view.far_wall_m, 0.01)
        << "yaw " << view.yaw;
  }
}

TEST(SuiteTest, EveryPixelSeesASurfaceNearTheDoorways) {
  // Oblique views past the doorways' edges: the passage through the wall is closed (jambs,
  // soffit, threshold), so no ray escapes between the two wall faces.
  const World suite = MakeTestSuite();
  const struct {
    double x, y, yaw;
  } views[] = {{3.0, -0.8, 0.5}, {3.0, 1.8, -0.5},  {-3.0, -0.5, 2.7},
               {-1.5, 3.0, 1.2}, {0.6, -3.0, -2.0}, {6.0, 0.5, M_PI}};
  for (const auto& v : views) {
    const cv::Mat depth = RenderDepth(suite, WorldFromCamera(v.x, v.y, v.yaw));
    EXPECT_EQ(cv::countNonZero(depth > 0), depth.rows * depth.cols)
        << "at " << v.x << ", " << v.y << " yaw " << v.yaw;
  }
}

TEST(SuiteTest, TheTourNeverWalksThroughAWallOrABox) {
  const World suite = MakeTestSuite();
  const SequenceSpec tour = MakeSequenceSpec("map_suite", 1);
  ASSERT_TRUE(tour.room.suite);
  const StereoRig rig = MakeRig(RigOptions{});
  double nearest_m = 1e9;
  for (double t = 0; t <= tour.path.duration_s(); t += 0.25) {
    const Rigid3d world_from_body = tour.path.WorldFromBody(t);
    for (const CameraInfo* cam : {&rig.left, &rig.right}) {
      const Eigen::Vector3d position = (world_from_body * cam->body_from_cam).translation;
      nearest_m = std::min(nearest_m, DistanceToNearestSurface(suite, position));
    }
  }
  // The doorway's jambs pass 0.5 m from the body centre, less the camera offset and sway.
  EXPECT_GT(nearest_m, 0.35);
  // Every room is visited: the tour reaches 3 m into each neighbour.
  const PlanarPose end = tour.path.PlannedAt(tour.path.duration_s());
  EXPECT_NEAR(end.x, kSuiteLaneX, 1e-9);
  EXPECT_NEAR(end.y, -1.0, 1e-9);
  double max_x = 0, min_x = 0, max_y = 0, min_y = 0;
  for (double t = 0; t <= tour.path.duration_s(); t += 0.5) {
    const PlanarPose p = tour.path.PlannedAt(t);
    max_x = std::max(max_x, p.x), min_x = std::min(min_x, p.x);
    max_y = std::max(max_y, p.y), min_y = std::min(min_y, p.y);
  }
  EXPECT_GT(max_x, 6.9);
  EXPECT_LT(min_x, -7.9);
  EXPECT_GT(max_y, 7.9);
  EXPECT_LT(min_y, -6.9);
}

// The building's run: through every doorway of the nine rooms three times, never through a
// wall or a box, every room's lane crossing reached, and back where the rounds began.
TEST(BuildingTest, TheTourVisitsEveryRoomAndNeverWalksThroughAWallOrABox) {
  RoomOptions options;
  options.texel_m = 0.02;
  options.building = true;
  const World building = MakeRoom(options);
  const SequenceSpec tour = MakeSequenceSpec("map_building", 1);
  ASSERT_TRUE(tour.room.building);
  const StereoRig rig = MakeRig(RigOptions{});
  const double step_m = options.width_m + kSuiteWallM;
  double nearest_m = 1e9;
  std::set<std::pair<int, int>> crossings;  // Rooms whose lane crossing the run stood on.
  for (double t = 0; t <= tour.path.duration_s(); t += 0.25) {
    const Rigid3d world_from_body = tour.path.WorldFromBody(t);
    for (const CameraInfo* cam : {&rig.left, &rig.right}) {
      const Eigen::Vector3d position = (world_from_body * cam->body_from_cam).translation;
      nearest_m = std::min(nearest_m, DistanceToNearestSurface(building, position));
    }
    const PlanarPose p = tour.path.PlannedAt(t);
    const int i = static_cast<int>(std::lround((p.x - kSuiteLaneX) / step_m));
    const int j = static_cast<int>(std::lround((p.y - kSuiteLaneY) / step_m));
    if (std::hypot(p.x - kSuiteLaneX - i * step_m, p.y - kSuiteLaneY - j * step_m) < 0.05) {
      crossings.insert({i, j});
    }
  }
  EXPECT_GT(nearest_m, 0.35);  // As in the suite: the jambs, less the camera offset and sway.
  EXPECT_EQ(crossings.size(), 9u);
  const PlanarPose end = tour.path.PlannedAt(tour.path.duration_s());
  EXPECT_NEAR(end.x, kSuiteLaneX, 1e-9);
  EXPECT_NEAR(end.y, kSuiteLaneY, 1e-9);
  // Four times the suite's run and more, at the sequences' 20 frames a second.
  EXPECT_GT(tour.path.duration_s(), 4 * MakeSequenceSpec("map_suite", 1).path.duration_s());
}

}  // namespace
}  // namespace visloc::sim
