// End-to-end: `visloc sim` renders a mapping sequence, `visloc map build` builds a map, and the
// map is scored against the simulator's exact ground truth: keyframe poses (via `visloc map
// export` + `visloc eval`) and map points against the true scene surfaces.

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "core/util/temp_dir.h"
#include "mapstore/map_store.h"
#include "sim/sequences.h"
#include "sim/world.h"
#include "tests/support/e2e.h"
#include "tests/support/process.h"

namespace visloc {
namespace {

using ::testing::HasSubstr;
using testing::JsonNumber;
using testing::ProcessResult;
using testing::Visloc;

TEST(MapBuildE2eTest, ShortSquareBuildsAnAccurateMap) {
  TempDir dir;
  // 150 frames: the first side of the square and the turn (10 s).
  ASSERT_EQ(Visloc({"sim", "--out", dir.path(), "--sequence", "map_square", "--frames", "150",
                    "--no-contact-sheet"})
                .exit_code,
            0);
  const std::string map_path = dir.File("square.db");
  const ProcessResult build =
      Visloc({"map", "build", "--dataset", dir.File("map_square"), "--out", map_path, "--json"});
  ASSERT_EQ(build.exit_code, 0) << build.err;
  EXPECT_THAT(build.out, HasSubstr("\"frames\":150"));
  // Each key once (disparity_rmse_px was written twice).
  for (const char* key : {"\"disparity_rmse_px\"", "\"loop_closures\"", "\"loop_adjustments\""}) {
    size_t count = 0;
    for (size_t at = build.out.find(key); at != std::string::npos; at = build.out.find(key, at + 1))
      ++count;
    EXPECT_EQ(count, 1u) << key;
  }
  EXPECT_LT(JsonNumber(build.out, "map", "reprojection_rmse_px"), 0.5);
  EXPECT_EQ(JsonNumber(build.out, "map", "tracking_failures"), 0);
  EXPECT_EQ(Visloc({"map", "verify", map_path}).exit_code, 0);

  ASSERT_EQ(Visloc({"map", "export", map_path, "--keyframes", dir.File("keyframes.tum")}).exit_code,
            0);
  const ProcessResult eval = Visloc({"eval", "--gt", dir.File("map_square/groundtruth_map.tum"),
                                     "--est", dir.File("keyframes.tum"), "--json"});
  ASSERT_EQ(eval.exit_code, 0) << eval.err;
  const double ate_rmse_m = JsonNumber(eval.out, "ate", "rmse");
  std::printf("keyframe ATE RMSE %.2f cm\n", 100 * ate_rmse_m);
  EXPECT_LT(ate_rmse_m, 0.015);  // issue target: 2 cm at 320x240; measured ~0.5 cm

  // Map points lie on the true surfaces: the map frame is the first left camera in the world.
  const Map map = mapstore::LoadMap(map_path);
  EXPECT_GT(map.points.size(), 500u);
  const Rigid3d world_from_map = sim::WorldFromMap(sim::RigOptions{});
  sim::RoomOptions room;
  room.texel_m = 0.05;  // geometry only
  const sim::World world = sim::MakeRoom(room);
  std::vector<double> distances;
  for (const MapPoint& p : map.points)
    distances.push_back(sim::DistanceToNearestSurface(world, world_from_map * p.position_in_map));
  std::sort(distances.begin(), distances.end());
  std::printf("map points to surfaces: median %.2f cm, 90%% %.2f cm\n",
              100 * distances[distances.size() / 2], 100 * distances[distances.size() * 9 / 10]);
  EXPECT_LT(distances[distances.size() / 2], 0.01);  // issue target: 1 cm
}

TEST(MapBuildE2eTest, MonocularOrMissingDatasetsAreRefusedClearly) {
  TempDir dir;
  const ProcessResult missing =
      Visloc({"map", "build", "--dataset", dir.File("nope"), "--out", dir.File("m.db")});
  EXPECT_EQ(missing.exit_code, 1);
  EXPECT_THAT(missing.err, HasSubstr("no such dataset directory"));
  const ProcessResult bad_threshold = Visloc({"map", "build", "--dataset", dir.path(), "--out",
                                              dir.File("m.db"), "--keyframe-rotation", "0"});
  EXPECT_EQ(bad_threshold.exit_code, 2);
  EXPECT_THAT(bad_threshold.err, HasSubstr("keyframe thresholds must be positive"));
  const ProcessResult bad_name = Visloc(
      {"map", "build", "--dataset", dir.path(), "--out", dir.File("m.db"), "--name", "../x"});
  EXPECT_EQ(bad_name.exit_code, 1);
  EXPECT_THAT(bad_name.err, HasSubstr("invalid map name '../x'"));
}

}  // namespace
}  // namespace visloc
