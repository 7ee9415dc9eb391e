// Maps across sessions end to end on the localization fixture, real binaries and map files:
// - `visloc map merge`: the map of the square (A) and a map built from another session through
//   the same room (the circle, B) become one map in A's frame; B's keyframes must land on ground
//   truth, the circle must localize in the merged map, and a map of a different room is refused;
// - `visloc map extend`: a map of the square's first third extended with the offset-square
//   session, placed by localizing its images in the map; a session in a different room localizes
//   nowhere, is refused and leaves the map file as it was;
// - `visloc map update`: the map of the room brought up to date with a session after the boxes
//   were moved; what the map expects is found again about as often as before the change.

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

#include "core/geometry/trajectory.h"
#include "core/util/temp_dir.h"
#include "core/util/text_file.h"
#include "dataset/tum.h"
#include "tests/support/e2e.h"
#include "tests/support/process.h"

namespace visloc {
namespace {

using ::testing::HasSubstr;
using testing::JsonNumber;
using testing::ProcessResult;
using testing::Visloc;

const std::string kData = VISLOC_LOCALIZATION_DATA;

// One column of a `--stats` CSV (`visloc localize` or `visloc stream`), a value per frame.
std::vector<double> StatsColumn(const std::string& stats_csv, const std::string& name) {
  std::ifstream in(stats_csv);
  std::string line;
  std::getline(in, line);
  std::vector<std::string> header;
  std::istringstream names(line);
  for (std::string field; std::getline(names, field, ',');) header.push_back(field);
  const size_t column = std::find(header.begin(), header.end(), name) - header.begin();
  std::vector<double> values;
  while (std::getline(in, line)) {
    std::vector<std::string> fields;
    std::istringstream row(line);
    for (std::string field; std::getline(row, field, ',');) fields.push_back(field);
    values.push_back(column < fields.size() ? std::stod(fields[column]) : NAN);
  }
  return values;
}

// The median, over localized frames, of inliers per predicted-visible map point: how much of
// what the map expects to see is really there (from `visloc localize --stats`).
double MedianFoundRatio(const std::string& stats_csv) {
  const std::vector<double> predicted = StatsColumn(stats_csv, "predicted");
  const std::vector<double> inliers = StatsColumn(stats_csv, "inliers");
  std::vector<double> ratios;
  for (size_t i = 0; i < predicted.size() && i < inliers.size(); ++i) {
    if (predicted[i] > 0) ratios.push_back(inliers[i] / predicted[i]);
  }
  if (ratios.empty()) return 0.0;
  std::nth_element(ratios.begin(), ratios.begin() + ratios.size() / 2, ratios.end());
  return ratios[ratios.size() / 2];
}

class MapMergeE2eTest : public ::testing::Test {
 protected:
  // A map from a fixture sequence (each sequence is rendered in stereo).
  std::string BuildMap(const std::string& sequence) {
    const std::string path = dir_.File(sequence + ".db");
    const ProcessResult build =
        Visloc({"map", "build", "--dataset", kData + "/" + sequence, "--out", path});
    EXPECT_EQ(build.exit_code, 0) << build.err;
    return path;
  }
  TempDir dir_{"visloc_map_merge_e2e"};
};

TEST_F(MapMergeE2eTest, TwoSessionsOfOneRoomBecomeOneMapInTheFirstOnesFrame) {
  const std::string b = BuildMap("circle");
  const std::string merged = dir_.File("merged.db");
  const ProcessResult merge =
      Visloc({"map", "merge", kData + "/map.db", b, "--out", merged, "--name", "lab", "--json"});
  ASSERT_EQ(merge.exit_code, 0) << merge.err;
  EXPECT_GE(JsonNumber(merge.out, "inliers"), 40);
  EXPECT_LT(JsonNumber(merge.out, "inlier_rmse_m"), 0.02);
  // B's keyframes and A's along the seam were adjusted with the points; the circle's first 120
  // frames see part of the room, so A's keyframes beyond it were held. They fit their images
  // better.
  const double adjusted = JsonNumber(merge.out, "adjusted_keyframes");
  EXPECT_GT(adjusted, JsonNumber(merge.out, "keyframes_b"));
  EXPECT_LT(adjusted,
            JsonNumber(merge.out, "keyframes_a") + JsonNumber(merge.out, "keyframes_b") - 1);
  EXPECT_LT(JsonNumber(merge.out, "adjustment_final_rmse_px"),
            JsonNumber(merge.out, "adjustment_initial_rmse_px"));
  const int keyframes_a = static_cast<int>(JsonNumber(merge.out, "keyframes_a"));
  const int keyframes_b = static_cast<int>(JsonNumber(merge.out, "keyframes_b"));
  EXPECT_EQ(JsonNumber(merge.out, "keyframes"), keyframes_a + keyframes_b);

  // B's keyframes in A's frame against the circle's ground truth (the fixture renders every
  // sequence's ground truth in the square map's frame).
  const std::string keyframes = dir_.File("keyframes.tum");
  ASSERT_EQ(Visloc({"map", "export", merged, "--keyframes", keyframes, "--frame", "map"}).exit_code,
            0);
  // Both sessions were rendered from the same start time, so the keyframes' times repeat.
  const Trajectory all = testing::ReadTumLines(keyframes);
  ASSERT_EQ(static_cast<int>(all.size()), keyframes_a + keyframes_b);
  const Trajectory gt = ReadTum(kData + "/circle/groundtruth_map.tum");
  double worst_m = 0.0;
  for (int k = keyframes_a; k < keyframes_a + keyframes_b; ++k) {
    const auto truth = InterpolateAt(gt, all[k].timestamp_ns, 50'000'000);
    ASSERT_TRUE(truth.has_value());
    worst_m = std::max(worst_m, (truth->translation - all[k].pose.translation).norm());
  }
  EXPECT_LT(worst_m, 0.01) << "B's keyframes after the merge, farthest from ground truth";

  // The merged map localizes the circle, and says where it came from.
  const std::string trajectory = dir_.File("circle.tum");
  const ProcessResult localize = Visloc({"localize", "--map", merged, "--dataset",
                                         kData + "/circle", "--trajectory", trajectory, "--json"});
  ASSERT_EQ(localize.exit_code, 0) << localize.err;
  EXPECT_GE(JsonNumber(localize.out, "localized_fraction"), 0.99);
  const ProcessResult eval = Visloc(
      {"eval", "--gt", kData + "/circle/groundtruth_map.tum", "--est", trajectory, "--json"});
  EXPECT_LT(JsonNumber(eval.out, "translation_m", "median"), 0.01);
  const ProcessResult info = Visloc({"map", "info", merged, "--json"});
  EXPECT_THAT(info.out, HasSubstr("\"lineage\":\"merge('map' <- "));
  // A's rig error, stereo baseline and up are kept (the fixture's exact rig, and up from its
  // IMU with its floor), so the file is schema 6, not 2.
  EXPECT_THAT(info.out, HasSubstr("\"rig_error\":{\"floor_m\":0,\"drift_fraction\":0}"));
  EXPECT_NEAR(JsonNumber(info.out, "", "stereo_baseline_m"), 0.144, 1e-6);
  EXPECT_THAT(info.out, HasSubstr("\"schema_version\":6"));
  EXPECT_THAT(info.out, HasSubstr("\"source\":\"imu_floor\""));
  EXPECT_EQ(Visloc({"map", "verify", merged}).exit_code, 0);

  // Served: the merged map replaces the square's map on a running server; new sessions get it.
  TempDir maps("visloc_map_merge_served");
  std::filesystem::copy_file(kData + "/map.db", maps.File("lab.db"));
  testing::ServerProcess server(VISLOC_SERVER_PATH, maps.path());
  ASSERT_EQ(Visloc({"map", "upload", merged, "--server", server.address(), "--replace"}).exit_code,
            0);
  const ProcessResult served =
      Visloc({"map", "info", "lab", "--server", server.address(), "--json"});
  EXPECT_THAT(served.out, HasSubstr("\"lineage\":\"merge('map' <- "));
  EXPECT_EQ(JsonNumber(served.out, "keyframes"), keyframes_a + keyframes_b);
  const ProcessResult stream = Visloc({"stream", "--server", server.address(), "--map", "lab",
                                       "--dataset", kData + "/circle", "--rate", "0", "--json"});
  ASSERT_EQ(stream.exit_code, 0) << stream.err;
  EXPECT_GE(JsonNumber(stream.out, "localized_fraction"), 0.99);
}

TEST_F(MapMergeE2eTest, MapsOfDifferentRoomsAreRefused) {
  const std::string other_room = BuildMap("outofmap");
  const std::string out = dir_.File("never.db");
  const ProcessResult merge = Visloc({"map", "merge", kData + "/map.db", other_room, "--out", out});
  EXPECT_EQ(merge.exit_code, 1);
  EXPECT_THAT(merge.err, HasSubstr("no verified overlap"));
  EXPECT_FALSE(std::filesystem::exists(out));
}

// The partial map served, a robot streaming the circle on it in real time, and the extended map
// uploaded as its replacement while the robot streams: the running session keeps the map it
// started with (frame by frame it predicts the points the partial map predicts in-process), a
// session started after the upload gets the extended one (which predicts more).
void ExpectRunningSessionsKeepTheOldMap(const std::string& partial, const std::string& extended,
                                        const TempDir& out) {
  const std::string in_partial = out.File("in_partial.csv"), running = out.File("running.csv"),
                    after = out.File("after.csv");
  ASSERT_EQ(
      Visloc({"localize", "--map", partial, "--dataset", kData + "/circle", "--stats", in_partial})
          .exit_code,
      0);
  TempDir maps("visloc_map_extend_served");
  std::filesystem::copy_file(partial, maps.File("lab.db"));
  testing::ServerProcess server(VISLOC_SERVER_PATH, maps.path());
  auto stream = [&](const std::string& stats, const std::string& rate) {
    // Nothing dropped or late however loaded the machine (a CI run under ASan dropped 1 of
    // 120 at 15 Hz), and the files' own bytes at both paces: the frames are compared one by one.
    return Visloc({"stream", "--server", server.address(), "--map", "lab", "--dataset",
                   kData + "/circle", "--rate", rate, "--encoding", "file", "--max-queued",
                   "1000", "--frame-deadline-ms", "600000", "--stats", stats, "--json"});
  };
  ProcessResult robot_result;
  std::thread robot([&] { robot_result = stream(running, "15"); });  // 120 frames: 8 s.
  // The replacement comes once the robot's session is open on the old map, however long the
  // robot takes to start.
  const bool robot_started = server.WaitForLog("event=session_start", 30000);
  // A map a robot is on is neither deleted nor replaced without --force, and the refusal says
  // how many sessions use it.
  const ProcessResult delete_in_use = Visloc({"map", "delete", "lab", "--server", server.address()});
  const ProcessResult replace_in_use = Visloc(
      {"map", "upload", extended, "--server", server.address(), "--name", "lab", "--replace"});
  const ProcessResult upload = Visloc({"map", "upload", extended, "--server", server.address(),
                                       "--name", "lab", "--replace", "--force"});
  robot.join();
  ASSERT_TRUE(robot_started) << server.Log();
  EXPECT_EQ(delete_in_use.exit_code, 1);
  EXPECT_THAT(delete_in_use.err,
              HasSubstr("map 'lab' is in use by 1 session; delete it anyway with visloc map "
                        "delete --force"));
  EXPECT_EQ(replace_in_use.exit_code, 1);
  EXPECT_THAT(replace_in_use.err, HasSubstr("replace it anyway with visloc map upload --replace "
                                            "--force"));
  ASSERT_EQ(upload.exit_code, 0) << upload.err;
  ASSERT_EQ(robot_result.exit_code, 0) << robot_result.err;
  EXPECT_EQ(JsonNumber(robot_result.out, "frames"), 120);
  const ProcessResult later = stream(after, "0");
  ASSERT_EQ(later.exit_code, 0) << later.err;
  const std::vector<double> expected = StatsColumn(in_partial, "predicted");
  const std::vector<double> kept = StatsColumn(running, "predicted");
  const std::vector<double> replaced = StatsColumn(after, "predicted");
  ASSERT_EQ(kept.size(), expected.size());
  ASSERT_EQ(replaced.size(), expected.size());
  int same_as_partial = 0, other_than_partial = 0;
  for (size_t i = 0; i < expected.size(); ++i) {
    same_as_partial += kept[i] == expected[i];
    other_than_partial += replaced[i] != expected[i];
  }
  EXPECT_EQ(same_as_partial, static_cast<int>(expected.size()));
  EXPECT_GT(other_than_partial, static_cast<int>(expected.size()) / 2);
}

TEST_F(MapMergeE2eTest, ExtendAddsASessionInTheMapsFrameAndRefusesAnotherRoom) {
  const std::string map = dir_.File("partial.db");
  ASSERT_EQ(
      Visloc({"map", "build", "--dataset", kData + "/map_square", "--frames", "96", "--out", map})
          .exit_code,
      0);
  const ProcessResult before = Visloc({"map", "info", map, "--json"});
  const std::string partial = dir_.File("partial_copy.db");
  std::filesystem::copy_file(map, partial);
  const ProcessResult extend =
      Visloc({"map", "extend", map, "--dataset", kData + "/query_square", "--json"});
  ASSERT_EQ(extend.exit_code, 0) << extend.err;
  ExpectRunningSessionsKeepTheOldMap(partial, map, dir_);
  // The session was found in the map as a robot is: its images localized (relocalization, then
  // tracking), and the keyframes that localized agree on where it lies; its points near the
  // map's then refined that placement.
  EXPECT_EQ(JsonNumber(extend.out, "session_localization", "frames"), 120);
  EXPECT_GT(JsonNumber(extend.out, "session_localization", "localized_frames"), 100);
  EXPECT_GE(JsonNumber(extend.out, "session_localization", "agreeing_frames"),
            0.9 * JsonNumber(extend.out, "session_localization", "localized_frames"));
  EXPECT_LT(JsonNumber(extend.out, "session_localization", "position_rmse_m"), 0.02);
  EXPECT_GE(JsonNumber(extend.out, "inliers"), 40);
  EXPECT_EQ(JsonNumber(extend.out, "keyframes"),
            JsonNumber(before.out, "keyframes") + JsonNumber(extend.out, "keyframes_b"));
  const ProcessResult info = Visloc({"map", "info", map, "--json"});
  EXPECT_THAT(info.out, HasSubstr("\"lineage\":\"extend('partial' <- "));

  const std::string trajectory = dir_.File("circle.tum");
  const ProcessResult localize = Visloc({"localize", "--map", map, "--dataset", kData + "/circle",
                                         "--trajectory", trajectory, "--json"});
  ASSERT_EQ(localize.exit_code, 0) << localize.err;
  EXPECT_GE(JsonNumber(localize.out, "localized_fraction"), 0.99);
  const ProcessResult eval = Visloc(
      {"eval", "--gt", kData + "/circle/groundtruth_map.tum", "--est", trajectory, "--json"});
  EXPECT_LT(JsonNumber(eval.out, "translation_m", "median"), 0.01);

  // A session in another room: refused, and the map file is the extended one, untouched.
  const std::string bytes_before = ReadFileBytes(map);
  const ProcessResult other = Visloc({"map", "extend", map, "--dataset", kData + "/outofmap"});
  EXPECT_EQ(other.exit_code, 1);
  EXPECT_THAT(other.err,
              HasSubstr("does not overlap the map: 0 of the session's 45 images localized"));
  EXPECT_EQ(ReadFileBytes(map), bytes_before);
}

TEST_F(MapMergeE2eTest, UpdateForAChangedPlaceRemovesWhatIsGoneAndRecoversTheFoundRatio) {
  // The changed room (boxes moved) in the map of the room as it was: what the map expects is
  // found less often than in the unchanged room.
  const auto found_ratio = [&](const std::string& map, const std::string& sequence) {
    const std::string stats = dir_.File(sequence + ".csv");
    const ProcessResult run =
        Visloc({"localize", "--map", map, "--dataset", kData + "/" + sequence, "--stats", stats});
    EXPECT_EQ(run.exit_code, 0) << run.err;
    return MedianFoundRatio(stats);
  };
  const double unchanged = found_ratio(kData + "/map.db", "query_square");
  const double changed_before = found_ratio(kData + "/map.db", "changed");
  EXPECT_LT(changed_before, unchanged - 0.02);

  const std::string map = dir_.File("lab.db");
  std::filesystem::copy_file(kData + "/map.db", map);
  const ProcessResult update =
      Visloc({"map", "update", map, "--dataset", kData + "/changed", "--json"});
  ASSERT_EQ(update.exit_code, 0) << update.err;
  // The changed room localizes all the same: its images place the session.
  EXPECT_GE(JsonNumber(update.out, "session_localization", "agreeing_frames"),
            0.9 * JsonNumber(update.out, "session_localization", "frames"));
  EXPECT_GT(JsonNumber(update.out, "removed_points"), 0);
  EXPECT_GT(JsonNumber(update.out, "added_points"), 0);
  const double changed_after = found_ratio(map, "changed");
  // The gap to the unchanged room closes (measured: 0.47 -> 0.57, against 0.51 unchanged).
  EXPECT_GT(changed_after, changed_before + 0.5 * (unchanged - changed_before));
  EXPECT_THAT(Visloc({"map", "info", map, "--json"}).out,
              HasSubstr("\"lineage\":\"update('map' <- "));
}

}  // namespace
}  // namespace visloc
