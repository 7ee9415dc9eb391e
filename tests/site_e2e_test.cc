// Up in every map: `visloc map build` finds the gravity direction (the accelerometer, a level
// body, the floor) and the map keeps it; `visloc map info` shows it. Checked against the exact
// ground truth of generated sequences and the real recordings' own (issue 57's targets).

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <map>

#include "core/util/check.h"
#include "core/util/random.h"
#include "core/util/strings.h"
#include "core/util/temp_dir.h"
#include "core/util/text_file.h"
#include "dataset/dataset.h"
#include "dataset/tum.h"
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
  // The accelerometer, with the room's floor (which barely moves a run that turns).
  EXPECT_EQ(gravity.source, MapGravity::Source::kImuAndFloor);
  const double error_deg = AngleDeg(gravity.up_in_map, TrueUpInMap(kData + "/map_square"));
  EXPECT_LT(error_deg, 0.2);
  EXPECT_LT(error_deg, 3 * gravity.sigma_deg);
  const ProcessResult info = Visloc({"map", "info", kData + "/map.db", "--json"});
  ASSERT_EQ(info.exit_code, 0) << info.err;
  EXPECT_NE(info.out.find("\"source\":\"imu_floor\""), std::string::npos) << info.out;
  EXPECT_NEAR(JsonNumber(info.out, "gravity", "sigma_deg"), gravity.sigma_deg, 1e-9);
  const ProcessResult text = Visloc({"map", "info", kData + "/map.db"});
  EXPECT_NE(text.out.find("from the IMU and floor, sigma"), std::string::npos) << text.out;
}

// Exports speak the site frame once the map knows up: the square was walked on a level floor,
// so its keyframes lie level there (the head's bob and the map's error: a few centimetres),
// while in the map frame, its first camera's, they need not.
TEST(SiteE2eTest, ExportsAreInTheLevelSiteFrameOnceTheMapKnowsUp) {
  TempDir dir("visloc_site_export");
  const auto heights = [&](const std::string& frame) {
    const std::string path = dir.File(frame + ".tum");
    const ProcessResult exported = Visloc(
        {"map", "export", kData + "/map.db", "--keyframes", path, "--frame", frame, "--json"});
    EXPECT_EQ(exported.exit_code, 0) << exported.err;
    EXPECT_NE(exported.out.find("\"frame\":\"" + frame + "\""), std::string::npos) << exported.out;
    double low = 1e9, high = -1e9;
    for (const StampedPose& k : testing::ReadTumLines(path)) {
      low = std::min(low, k.pose.translation.z());
      high = std::max(high, k.pose.translation.z());
    }
    return high - low;
  };
  EXPECT_LT(heights("site"), 0.04);
  EXPECT_GT(heights("map"), 1.0);  // The map's z is the first camera's optical axis.
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

// Surveyed spots: the robot localized at five places of the room (the map's keyframes there),
// each spot's position surveyed in the world frame to 1 cm (rms, 3-D). `map align` ties the map to
// the world, and every keyframe lands within 2 cm of where it truly was; a spot surveyed 1 m off is
// named and refused, the map untouched.
TEST(SiteE2eTest, SurveyedSpotsTieTheMapToTheSiteAndAWrongSpotIsRefusedByName) {
  TempDir dir("visloc_align");
  const std::string map_path = dir.File("square.db");
  std::filesystem::copy_file(kData + "/map.db", map_path);
  const Map map = mapstore::LoadMap(map_path);
  const Dataset dataset = ReadDataset(kData + "/map_square");
  const auto true_position = [&](int64_t t_ns) {
    const auto world_from_body = InterpolateAt(dataset.world_from_body, t_ns, 50'000'000);
    EXPECT_TRUE(world_from_body.has_value());
    return (world_from_body.value_or(Rigid3d()) * dataset.left.body_from_cam).translation;
  };
  Rng rng(11);
  std::string pairs = "name,map_x,map_y,map_z,site_x,site_y,site_z\n";
  std::string wrong = pairs;
  const size_t n = map.keyframes.size();
  for (int s = 0; s < 5; ++s) {
    const Keyframe& k = map.keyframes[s * (n - 1) / 4];
    Eigen::Vector3d site = true_position(k.timestamp_ns);
    for (int i = 0; i < 3; ++i) site[i] += rng.Normal(0, 0.01 / std::sqrt(3.0));  // 1 cm rms.
    const Eigen::Vector3d& in_map = k.map_from_cam.translation;
    const auto line = [&](const Eigen::Vector3d& at) {
      return StrCat("spot ", s + 1, ",", in_map.x(), ",", in_map.y(), ",", in_map.z(), ",", at.x(),
                    ",", at.y(), ",", at.z(), "\n");
    };
    pairs += line(site);
    wrong += line(s == 2 ? Eigen::Vector3d(site + Eigen::Vector3d(1.0, 0, 0)) : site);
  }
  WriteFileAtomically(dir.File("wrong.csv"), wrong);
  const ProcessResult refused =
      Visloc({"map", "align", map_path, "--pairs", dir.File("wrong.csv")});
  EXPECT_NE(refused.exit_code, 0);
  EXPECT_NE(refused.err.find("pair 'spot 3' is "), std::string::npos) << refused.err;
  EXPECT_NE(refused.err.find("a wrong pair?"), std::string::npos) << refused.err;
  EXPECT_FALSE(mapstore::LoadMap(map_path).metadata.site.has_value());

  WriteFileAtomically(dir.File("spots.csv"), pairs);
  const ProcessResult aligned =
      Visloc({"map", "align", map_path, "--pairs", dir.File("spots.csv"), "--json"});
  ASSERT_EQ(aligned.exit_code, 0) << aligned.err;
  EXPECT_LT(JsonNumber(aligned.out, "rms_m"), 0.02);
  EXPECT_LT(JsonNumber(aligned.out, "site_z_from_up_deg"), 1.0);  // The world's z is up.
  const Map tied = mapstore::LoadMap(map_path);
  ASSERT_TRUE(tied.metadata.site.has_value());
  EXPECT_EQ(tied.metadata.site->pairs, 5);
  double worst_m = 0;
  for (const Keyframe& k : tied.keyframes) {
    const Eigen::Vector3d in_site = tied.metadata.site->site_from_map * k.map_from_cam.translation;
    worst_m = std::max(worst_m, (in_site - true_position(k.timestamp_ns)).norm());
  }
  EXPECT_LT(worst_m, 0.02) << "every keyframe within 2 cm of its true site position";
  EXPECT_EQ(Visloc({"map", "verify", map_path}).exit_code, 0);
  const ProcessResult info = Visloc({"map", "info", map_path});
  EXPECT_NE(info.out.find("site          tied to pairs "), std::string::npos) << info.out;
}

// A run's poses in the map beside the same stamps of a reference trajectory (motion capture's)
// tie the map to the reference's frame; pair files that are not pairs are named by line.
TEST(SiteE2eTest, ARunBesideAReferenceTrajectoryTiesTheMapAndBrokenPairFilesAreNamed) {
  TempDir dir("visloc_align_trajectory");
  const std::string map_path = dir.File("square.db");
  std::filesystem::copy_file(kData + "/map.db", map_path);
  const std::string walk = kData + "/outward";  // A 0.8 m circle: the pairs span a plane.
  ASSERT_EQ(Visloc({"localize", "--map", map_path, "--dataset", walk, "--trajectory",
                    dir.File("est.tum"), "--frames", "0::4"})
                .exit_code,
            0);
  // The reference: the walk's ground truth (map frame) in a motion-capture room's frame, turned
  // and moved against the map's.
  const Rigid3d mocap_from_map(
      Eigen::Quaterniond(Eigen::AngleAxisd(1.2, Eigen::Vector3d(0.2, 1.0, -0.3).normalized())),
      Eigen::Vector3d(4.0, -2.5, 1.3));
  const Trajectory truth = testing::ReadTumLines(walk + "/groundtruth_map.tum");
  Trajectory reference;
  for (const StampedPose& pose : testing::ReadTumLines(dir.File("est.tum"))) {
    const auto at = InterpolateAt(truth, pose.timestamp_ns, 1'000'000);
    ASSERT_TRUE(at.has_value()) << pose.timestamp_ns;
    reference.push_back({pose.timestamp_ns, mocap_from_map * *at});
  }
  ASSERT_GT(reference.size(), 20u);
  WriteTum(dir.File("mocap.tum"), reference);
  const ProcessResult aligned =
      Visloc({"map", "align", map_path, "--trajectory", dir.File("est.tum"), "--reference",
              dir.File("mocap.tum"), "--json"});
  ASSERT_EQ(aligned.exit_code, 0) << aligned.err;
  EXPECT_LT(JsonNumber(aligned.out, "rms_m"), 0.01);
  const Map tied = mapstore::LoadMap(map_path);
  ASSERT_TRUE(tied.metadata.site.has_value());
  EXPECT_EQ(tied.metadata.site->pairs, static_cast<int>(reference.size()));
  // Every keyframe where the reference's frame has it.
  double worst_m = 0;
  for (const Keyframe& k : tied.keyframes) {
    const Eigen::Vector3d& p = k.map_from_cam.translation;
    worst_m =
        std::max(worst_m, (tied.metadata.site->site_from_map * p - mocap_from_map * p).norm());
  }
  EXPECT_LT(worst_m, 0.02);

  // Broken pair files: refused with the file and line, and the map left as it was.
  const std::string before = ReadFileBytes(map_path);
  const auto refused = [&](const std::string& name, const std::string& text,
                           const std::string& expected) {
    WriteFileAtomically(dir.File(name), text);
    const ProcessResult result = Visloc({"map", "align", map_path, "--pairs", dir.File(name)});
    EXPECT_EQ(result.exit_code, 1) << name;
    EXPECT_NE(result.err.find(expected), std::string::npos) << name << ": " << result.err;
  };
  refused("six.csv", "a,1,2,3,4,5,6\nb,1,2,3,4,5\n",
          "six.csv:2: expected NAME,MAP_X,MAP_Y,MAP_Z,SITE_X,SITE_Y,SITE_Z, found 6 fields");
  refused("word.csv", "a,0,0,0,0,0,0\nb,1,0,0,1,0,x\nc,0,1,0,0,1,0\n",
          "word.csv:2: the coordinates are not all finite numbers");
  refused("two.csv", "a,0,0,0,0,0,0\nb,1,0,0,1,0,0\n", "2 position pairs; a rigid fit needs");
  EXPECT_EQ(ReadFileBytes(map_path), before);
}

// A CSV's rows as field maps by its header.
std::vector<std::map<std::string, std::string>> ReadCsv(const std::string& path) {
  const std::vector<TextLine> lines = ReadTextLines(path);
  std::vector<std::map<std::string, std::string>> rows;
  if (lines.empty()) return rows;
  const std::vector<std::string> header = Split(lines[0].text, ',');
  for (size_t i = 1; i < lines.size(); ++i) {
    const std::vector<std::string> fields = Split(lines[i].text, ',');
    std::map<std::string, std::string> row;
    for (size_t f = 0; f < header.size() && f < fields.size(); ++f) row[header[f]] = fields[f];
    rows.push_back(std::move(row));
  }
  return rows;
}

// Issue 57's localizability targets on a walk facing out of the mapped square (views the map
// never had, many frames limited): the frames the localizer reported limited were predicted
// poor from the map alone, and the frames predicted good localized.
TEST(SiteE2eTest, TheMapAlonePredictsWhereAWalkFacingOutOfItWentLimited) {
  const TempDir dir("visloc-localizability");
  const std::string walk = kData + "/outward";
  ASSERT_EQ(Visloc({"localize", "--map", kData + "/map.db", "--dataset", walk, "--stats",
                    dir.File("walk.csv")})
                .exit_code,
            0);
  const ProcessResult grid =
      Visloc({"map", "localizability", kData + "/map.db", "--out", dir.File("grid"), "--at",
              walk + "/groundtruth_map.tum", "--json"});
  ASSERT_EQ(grid.exit_code, 0) << grid.err;
  EXPECT_NE(grid.out.find("\"frame\":\"level\""), std::string::npos) << grid.out;

  // One row per cell and heading; the picture written.
  const int poses =
      static_cast<int>(JsonNumber(grid.out, "cells_x") * JsonNumber(grid.out, "cells_y") * 16);
  EXPECT_EQ(ReadCsv(dir.File("grid.csv")).size(), static_cast<size_t>(poses));
  EXPECT_EQ(static_cast<int>(JsonNumber(grid.out, "poses")), poses);
  EXPECT_GT(std::filesystem::file_size(dir.File("grid.png")), 10'000u);

  std::map<std::string, std::map<std::string, std::string>> predicted;
  for (auto& row : ReadCsv(dir.File("grid.path.csv"))) predicted[row["timestamp_ns"]] = row;
  int limited = 0, limited_poor = 0, predicted_good = 0, good_localized = 0;
  for (auto& frame : ReadCsv(dir.File("walk.csv"))) {
    ASSERT_TRUE(predicted.count(frame["timestamp_ns"])) << frame["timestamp_ns"];
    const auto& p = predicted[frame["timestamp_ns"]];
    const bool poor_status = frame["status"] == "lost" || frame["status"] == "limited";
    limited += poor_status;
    limited_poor += poor_status && p.at("good") == "0";
    predicted_good += p.at("good") == "1";
    good_localized +=
        p.at("good") == "1" && (frame["status"] == "tracking" || frame["status"] == "relocalized");
  }
  ASSERT_GT(limited, 20) << "the walk should go limited facing out";
  ASSERT_GT(predicted_good, 20);
  EXPECT_GE(limited_poor, 0.9 * limited) << limited_poor << " of " << limited;
  EXPECT_GE(good_localized, 0.9 * predicted_good) << good_localized << " of " << predicted_good;
}

// The server answers a map's grid over gRPC as the map file gives it, and names what it refuses.
TEST(SiteE2eTest, TheServerAnswersAMapsLocalizabilityAsTheFileGivesIt) {
  const TempDir dir("visloc-localizability-server");
  std::filesystem::create_directories(dir.File("maps"));
  std::filesystem::copy_file(kData + "/map.db", dir.File("maps/square.db"));
  testing::ServerProcess server(VISLOC_SERVER_PATH, dir.File("maps"));
  const ProcessResult remote =
      Visloc({"map", "localizability", "square", "--server", server.address(), "--out",
              dir.File("remote"), "--cell", "0.4", "--json"});
  ASSERT_EQ(remote.exit_code, 0) << remote.err;
  const ProcessResult local = Visloc(
      {"map", "localizability", kData + "/map.db", "--out", dir.File("local"), "--cell", "0.4"});
  ASSERT_EQ(local.exit_code, 0) << local.err;
  EXPECT_EQ(ReadFileBytes(dir.File("remote.csv")), ReadFileBytes(dir.File("local.csv")));
  EXPECT_GT(JsonNumber(remote.out, "good_poses"), 0);

  const ProcessResult unknown = Visloc(
      {"map", "localizability", "nosuch", "--server", server.address(), "--out", dir.File("x")});
  EXPECT_NE(unknown.exit_code, 0);
  EXPECT_NE(unknown.err.find("no map named 'nosuch'"), std::string::npos) << unknown.err;
  const ProcessResult too_fine =
      Visloc({"map", "localizability", "square", "--server", server.address(), "--out",
              dir.File("x"), "--cell", "0.05", "--headings", "72"});
  EXPECT_NE(too_fine.exit_code, 0);
  EXPECT_NE(too_fine.err.find("take larger cells or fewer headings"), std::string::npos)
      << too_fine.err;
  const ProcessResult at_remote =
      Visloc({"map", "localizability", "square", "--server", server.address(), "--out",
              dir.File("x"), "--at", kData + "/outward/groundtruth_map.tum"});
  EXPECT_EQ(at_remote.exit_code, 2) << at_remote.err;  // A usage error.
}

// Robots hear their pose in the map's site frame too (z up), and `localize` and `stream` write
// it: the same poses as the map frame's, turned by the map's site_from_map.
TEST(SiteE2eTest, ARobotsPosesComeInTheSiteFrameAsTheMapTurnsThem) {
  const TempDir dir("visloc-site-poses");
  std::filesystem::create_directories(dir.File("maps"));
  std::filesystem::copy_file(kData + "/map.db", dir.File("maps/square.db"));
  const std::string walk = kData + "/query_square";
  const std::vector<std::string> frames = {"--frames", "120"};
  auto run = [&](std::vector<std::string> args) {
    args.insert(args.end(), frames.begin(), frames.end());
    const ProcessResult result = Visloc(args);
    EXPECT_EQ(result.exit_code, 0) << result.err;
  };
  run({"localize", "--map", kData + "/map.db", "--dataset", walk, "--trajectory",
       dir.File("map.tum")});
  run({"localize", "--map", kData + "/map.db", "--dataset", walk, "--trajectory",
       dir.File("site.tum"), "--frame", "site"});
  testing::ServerProcess server(VISLOC_SERVER_PATH, dir.File("maps"));
  // As fast as the server answers, every frame answered: at the dataset's pace a frame that
  // waits past its deadline on a loaded host is dropped, and its pose missing is not what this
  // test is about.
  run({"stream", "--server", server.address(), "--map", "square", "--dataset", walk, "--rate", "0",
       "--trajectory", dir.File("streamed.tum"), "--frame", "site"});

  const std::optional<Rigid3d> site_from_map =
      SiteFromMap(mapstore::LoadMap(kData + "/map.db").metadata);
  ASSERT_TRUE(site_from_map.has_value());
  const Trajectory in_map = testing::ReadTumLines(dir.File("map.tum"));
  const Trajectory in_site = testing::ReadTumLines(dir.File("site.tum"));
  const Trajectory streamed = testing::ReadTumLines(dir.File("streamed.tum"));
  ASSERT_EQ(in_map.size(), 120u);
  ASSERT_EQ(in_site.size(), in_map.size());
  ASSERT_EQ(streamed.size(), in_map.size());
  for (size_t i = 0; i < in_map.size(); ++i) {
    const Rigid3d expected = *site_from_map * in_map[i].pose;
    EXPECT_LT((in_site[i].pose.translation - expected.translation).norm(), 1e-6) << i;
    // Through the server the frames travel encoded and tracking differs by a millimetre; a
    // wrong frame would be metres or a right angle off.
    EXPECT_LT((streamed[i].pose.translation - expected.translation).norm(), 0.01) << i;
    EXPECT_LT(streamed[i].pose.rotation.angularDistance(expected.rotation), 0.01) << i;
  }
  // The walk's camera stays level: its optical axis in the site frame is horizontal.
  const Eigen::Vector3d forward = in_site[60].pose.rotation * Eigen::Vector3d::UnitZ();
  EXPECT_LT(std::abs(forward.z()), 0.05) << forward.transpose();

  // A map that records no up has no site frame: refused by name, not written in another frame.
  Map no_up = mapstore::LoadMap(kData + "/map.db");
  no_up.metadata.gravity.reset();
  mapstore::SaveMap(no_up, dir.File("no_up.db"));
  std::vector<std::string> refused_args = {"localize",        "--map",   dir.File("no_up.db"),
                                           "--dataset",       walk,      "--trajectory",
                                           dir.File("x.tum"), "--frame", "site",
                                           "--frames",        "5"};
  const ProcessResult refused = Visloc(refused_args);
  EXPECT_NE(refused.exit_code, 0);
  EXPECT_NE(refused.err.find("records no up, so it has no site frame"), std::string::npos)
      << refused.err;
}

}  // namespace
}  // namespace visloc
