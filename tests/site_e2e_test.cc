// Up in every map: `visloc map build` finds the gravity direction (the accelerometer, a level
// body, the floor) and the map keeps it; `visloc map info` shows it. Checked against the exact
// ground truth of generated sequences and the real recordings' own (issue 57's targets).

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include "core/util/temp_dir.h"
#include "dataset/dataset.h"
#include "mapstore/map_store.h"
#include "tests/support/e2e.h"
#include "tests/support/process.h"

namespace visloc {
namespace {

using testing::JsonNumber;
using testing::ProcessResult;
using testing::Visloc;

const std::string kData = VISLOC_LOCALIZATION_DATA;
const std::string kReal = VISLOC_REAL_DATA;

double AngleDeg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b)) * 180.0 / M_PI;
}

// Up in the map frame (the first left camera's) from a recording's ground truth, whose world
// frame has z up: R_world_cam0(first frame)^-1 z.
Eigen::Vector3d TrueUpInMap(const std::string& dataset_dir) {
  const Dataset dataset = ReadDataset(dataset_dir);
  EXPECT_FALSE(dataset.world_from_body.empty()) << dataset_dir;
  const int64_t first_ns = dataset.frames.front().timestamp_ns;
  // The ground truth may start after the first frame (EuRoC V1_01: at frame 21): its first
  // pose then, for a recording still at its start.
  const auto world_from_body = InterpolateAt(dataset.world_from_body, first_ns, 50'000'000);
  const Rigid3d body = world_from_body ? *world_from_body : dataset.world_from_body.front().pose;
  return (body * dataset.left.body_from_cam).rotation.inverse() * Eigen::Vector3d::UnitZ();
}

MapGravity GravityOf(const std::string& map_path) {
  const Map map = mapstore::LoadMap(map_path);
  EXPECT_TRUE(map.metadata.gravity.has_value()) << map_path;
  return map.metadata.gravity.value_or(MapGravity{});
}

TEST(SiteE2eTest, AGeneratedMapKnowsUpFromItsAccelerometerWithinAFifthOfADegree) {
  const MapGravity gravity = GravityOf(kData + "/map.db");
  EXPECT_EQ(gravity.source, MapGravity::Source::kImu);
  const double error_deg = AngleDeg(gravity.up_in_map, TrueUpInMap(kData + "/map_square"));
  EXPECT_LT(error_deg, 0.2);
  EXPECT_LT(error_deg, 3 * gravity.sigma_deg);
  const ProcessResult info = Visloc({"map", "info", kData + "/map.db", "--json"});
  ASSERT_EQ(info.exit_code, 0) << info.err;
  EXPECT_NE(info.out.find("\"source\":\"imu\""), std::string::npos) << info.out;
  EXPECT_NEAR(JsonNumber(info.out, "gravity", "sigma_deg"), gravity.sigma_deg, 1e-9);
  const ProcessResult text = Visloc({"map", "info", kData + "/map.db"});
  EXPECT_NE(text.out.find("from the IMU, sigma"), std::string::npos) << text.out;
}

// A rig mounted pitched and rolled, no accelerometer: the map frame is tilted, and the floor
// beneath the keyframes says by how much.
TEST(SiteE2eTest, ATiltedRigWithoutAnImuFindsUpFromTheFloorWithinADegree) {
  TempDir dir("visloc_site");
  const ProcessResult sim =
      Visloc({"sim", "--out", dir.path(), "--no-contact-sheet", "--sequence", "map_square", "--fps",
              "5", "--frames", "120", "--camera-pitch", "20", "--camera-roll", "15"});
  ASSERT_EQ(sim.exit_code, 0) << sim.err;
  const std::string sequence = dir.File("map_square");
  std::filesystem::remove_all(sequence + "/mav0/imu0");
  const ProcessResult build = Visloc({"map", "build", "--dataset", sequence, "--out",
                                      dir.File("tilted.db"), "--rig-error", "0,0"});
  ASSERT_EQ(build.exit_code, 0) << build.err;
  EXPECT_NE(build.out.find("up: from the floor"), std::string::npos) << build.out;
  const MapGravity gravity = GravityOf(dir.File("tilted.db"));
  EXPECT_EQ(gravity.source, MapGravity::Source::kFloor);
  const Eigen::Vector3d truth = TrueUpInMap(sequence);
  EXPECT_GT(AngleDeg(truth, -Eigen::Vector3d::UnitY()), 20.0);  // The map frame is tilted ...
  EXPECT_LT(AngleDeg(gravity.up_in_map, truth), 1.0);           // ... and up is found.
  EXPECT_LT(AngleDeg(gravity.up_in_map, truth), 3 * gravity.sigma_deg);

  // Declared level instead: the body's z, exactly (the generated head is level at its start to
  // its gait's sway, a degree).
  const ProcessResult level = Visloc({"map", "build", "--dataset", sequence, "--out",
                                      dir.File("level.db"), "--rig-error", "0,0", "--level-body"});
  ASSERT_EQ(level.exit_code, 0) << level.err;
  const MapGravity declared = GravityOf(dir.File("level.db"));
  EXPECT_EQ(declared.source, MapGravity::Source::kLevelRig);
  EXPECT_LT(AngleDeg(declared.up_in_map, truth), 1.5);
}

// EuRoC V1_01's MAV stands still for the whole snippet: the accelerometer's bias (estimated by
// the recording's own ground truth at 0.55 m/s^2) cannot be told from gravity, and the map's
// sigma says so.
TEST(SiteE2eTest, AStillRealRecordingsUpIsWithinItsSigmaOfTheGroundTruth) {
  const std::string euroc = kReal + "/euroc_v1_01_micro";
  if (!std::filesystem::is_directory(euroc)) GTEST_SKIP() << "no real recordings at " << kReal;
  TempDir dir("visloc_site_real");
  const ProcessResult build =
      Visloc({"map", "build", "--dataset", euroc, "--out", dir.File("v1.db")});
  ASSERT_EQ(build.exit_code, 0) << build.err;
  EXPECT_NE(build.out.find("up: from the accelerometer"), std::string::npos) << build.out;
  const MapGravity gravity = GravityOf(dir.File("v1.db"));
  EXPECT_EQ(gravity.source, MapGravity::Source::kImu);
  const double error_deg = AngleDeg(gravity.up_in_map, TrueUpInMap(euroc));
  EXPECT_LT(error_deg, 3.0);
  EXPECT_LT(error_deg, 2 * gravity.sigma_deg);
  EXPECT_GT(gravity.sigma_deg, 1.0);
}

}  // namespace
}  // namespace visloc
