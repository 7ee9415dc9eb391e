// End-to-end on real recordings (../shared/real, read in place; tests/CMakeLists.txt names the
// folder): what a lab's first hour with visloc does. A real stereo rig (EuRoC: two cameras with
// their own intrinsics, radial-tangential lenses and T_BS, to be rectified) and the simplest one
// (KITTI: rectified, no distortion, a car at 8 m/s) must check, map, localize in-process and
// through the real server, and relocalize a single frame.

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>

#include "core/util/temp_dir.h"
#include "core/util/text_file.h"
#include "dataset/dataset.h"
#include "dataset/tum.h"
#include "tests/support/e2e.h"
#include "tests/support/process.h"

namespace visloc {
namespace {

using ::testing::HasSubstr;
using testing::JsonNumber;
using testing::ProcessResult;
using testing::ServerProcess;
using testing::Visloc;

const std::string kReal = VISLOC_REAL_DATA;
const std::string kEuroc = kReal + "/euroc_v1_01_micro";
const std::string kKitti = kReal + "/kitti00_first11";
// A car on KITTI 01's highway on-ramp, 51 frames, with KITTI's ground truth.
const std::string kOnRamp = kReal + "/kitti01_first51";
// A MAV shaken by hand in EuRoC's Machine Hall, with the left camera's ground truth.
const std::string kMachineHall = kReal + "/euroc_mh01_moving";
const std::string kMachineHallTruth = kMachineHall + "/groundtruth_cam0_tum.txt";

class RealDataE2eTest : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!std::filesystem::is_directory(kEuroc) || !std::filesystem::is_directory(kKitti)) {
      GTEST_SKIP() << "no real recordings at " << kReal << " (set VISLOC_REAL_DATA)";
    }
  }
  TempDir dir_{"visloc_real"};
};

// The spread of a still camera's poses: {position max m, rotation max deg}.
std::pair<double, double> Spread(const std::string& trajectory) {
  const ProcessResult spread = Visloc({"eval", "--est", trajectory, "--spread", "--json"});
  EXPECT_EQ(spread.exit_code, 0) << spread.err;
  return {JsonNumber(spread.out, "position_m", "max"),
          JsonNumber(spread.out, "rotation_deg", "max")};
}

TEST_F(RealDataE2eTest, EurocChecksMapsAndLocalizesEveryFrameInProcessAndThroughTheServer) {
  const ProcessResult check = Visloc({"dataset", "check", kEuroc, "--json"});
  ASSERT_EQ(check.exit_code, 0) << check.out << check.err;
  EXPECT_LT(JsonNumber(check.out, "row_difference_median_px"), 0.5);
  EXPECT_GT(JsonNumber(check.out, "stereo_matches_median"), 500);
  EXPECT_NEAR(JsonNumber(check.out, "baseline_m"), 0.110, 0.001);

  // The camera stands still: one keyframe, whose stereo points are the map.
  const std::string map = dir_.File("maps/euroc.db");
  std::filesystem::create_directories(dir_.File("maps"));
  const ProcessResult build = Visloc({"map", "build", "--dataset", kEuroc, "--out", map, "--json"});
  ASSERT_EQ(build.exit_code, 0) << build.err;
  const double points = JsonNumber(build.out, "points");
  std::printf("EuRoC map: %.0f points, %.0f keyframes\n", points,
              JsonNumber(build.out, "keyframes"));
  EXPECT_GE(points, 500);
  EXPECT_EQ(JsonNumber(build.out, "tracking_failures"), 0);
  EXPECT_EQ(Visloc({"map", "verify", map}).exit_code, 0);

  const std::string local = dir_.File("local.tum");
  const ProcessResult localize =
      Visloc({"localize", "--map", map, "--dataset", kEuroc, "--trajectory", local, "--json"});
  ASSERT_EQ(localize.exit_code, 0) << localize.err;
  EXPECT_EQ(JsonNumber(localize.out, "frames"), 95);
  EXPECT_EQ(JsonNumber(localize.out, "localized_fraction"), 1.0);
  const auto [position_m, rotation_deg] = Spread(local);
  std::printf("in-process spread: %.2f mm, %.3f deg\n", 1e3 * position_m, rotation_deg);
  EXPECT_LE(position_m, 0.005);
  EXPECT_LE(rotation_deg, 0.2);

  ServerProcess server(VISLOC_SERVER_PATH, dir_.File("maps"));
  const std::string streamed = dir_.File("stream.tum");
  const ProcessResult stream =
      Visloc({"stream", "--server", server.address(), "--map", "euroc", "--dataset", kEuroc,
              "--rate", "0", "--trajectory", streamed, "--json"});
  ASSERT_EQ(stream.exit_code, 0) << stream.err;
  EXPECT_EQ(JsonNumber(stream.out, "errors"), 0);
  EXPECT_EQ(JsonNumber(stream.out, "localized_fraction"), 1.0);
  const auto [stream_position_m, stream_rotation_deg] = Spread(streamed);
  EXPECT_LE(stream_position_m, 0.005);
  EXPECT_LE(stream_rotation_deg, 0.2);

  // One real frame, no session: where was it taken?
  const Dataset dataset = ReadDataset(kEuroc);
  const ProcessResult single =
      Visloc({"relocalize", "--server", server.address(), "--map", "euroc", "--dataset", kEuroc,
              dataset.frames[50].left_path, "--json"});
  ASSERT_EQ(single.exit_code, 0) << single.out << single.err;
  EXPECT_GT(JsonNumber(single.out, "inliers"), 100);
  const Trajectory in_process = ReadTum(local);
  const double x = JsonNumber(single.out, "tx"), y = JsonNumber(single.out, "ty"),
               z = JsonNumber(single.out, "tz");
  EXPECT_LT((Eigen::Vector3d(x, y, z) - in_process[50].pose.translation).norm(), 0.01);
}

TEST_F(RealDataE2eTest, OrbMapsTheEurocSnippetToo) {
  // The camera stands still: the first 20 frames make the same one-keyframe map.
  const ProcessResult build = Visloc({"map", "build", "--dataset", kEuroc, "--features", "orb",
                                      "--frames", "20", "--out", dir_.File("orb.db"), "--json"});
  ASSERT_EQ(build.exit_code, 0) << build.err;
  std::printf("EuRoC ORB map: %.0f points\n", JsonNumber(build.out, "points"));
  EXPECT_GE(JsonNumber(build.out, "points"), 500);
}

TEST_F(RealDataE2eTest, KittiTracksEveryFrameAndMovesLikeACar) {
  const std::string map = dir_.File("kitti.db");
  const std::string frames = dir_.File("frames.tum");
  const ProcessResult build =
      Visloc({"map", "build", "--dataset", kKitti, "--out", map, "--trajectory", frames, "--json"});
  ASSERT_EQ(build.exit_code, 0) << build.err;
  EXPECT_EQ(JsonNumber(build.out, "tracking_failures"), 0);
  EXPECT_GE(JsonNumber(build.out, "points"), 1000);
  // Forward (the camera's z) at about 0.8 m a frame, hardly sideways or up.
  const Trajectory poses = ReadTum(frames);
  ASSERT_EQ(poses.size(), 11u);
  for (size_t i = 1; i < poses.size(); ++i) {
    const Eigen::Vector3d step = poses[i].pose.translation - poses[i - 1].pose.translation;
    EXPECT_GT(step.z(), 0.6) << "frame " << i;
    EXPECT_LT(step.z(), 0.9) << "frame " << i;
    EXPECT_LT(std::hypot(step.x(), step.y()), 0.1) << "frame " << i;
  }
  std::printf("KITTI: %.2f m forward over 10 frames\n",
              poses.back().pose.translation.z() - poses.front().pose.translation.z());
  const ProcessResult localize = Visloc({"localize", "--map", map, "--dataset", kKitti, "--json"});
  ASSERT_EQ(localize.exit_code, 0) << localize.err;
  EXPECT_EQ(JsonNumber(localize.out, "localized_fraction"), 1.0);
  // The first fix, then the second frame's 0.7 m jump from a prior that knew no velocity (taken
  // at once, strongly supported, but reported relocalized), then tracking at the car's speed.
  EXPECT_EQ(JsonNumber(localize.out, "statuses", "relocalized"), 2);
  EXPECT_EQ(JsonNumber(localize.out, "statuses", "tracking"), 9);
}

// Frames [first, last) of the EuRoC snippet as a recording of their own in `out` (images linked,
// not copied): a second session through the same place.
std::string EurocPart(const std::string& out, int first, int last) {
  for (const char* cam : {"cam0", "cam1"}) {
    const std::filesystem::path from = std::filesystem::path(kEuroc) / "mav0" / cam;
    const std::filesystem::path to = std::filesystem::path(out) / "mav0" / cam;
    std::filesystem::create_directories(to / "data");
    std::filesystem::copy_file(from / "sensor.yaml", to / "sensor.yaml");
    std::ifstream rows(from / "data.csv");
    std::ofstream part(to / "data.csv");
    std::string row;
    std::getline(rows, row);
    part << row << "\n";
    for (int i = 0; std::getline(rows, row); ++i) {
      if (i < first || i >= last) continue;
      part << row << "\n";
      const std::string image =
          row.substr(row.find(',') + 1, row.find_last_not_of("\r") - row.find(','));
      std::filesystem::create_symlink(from / "data" / image, to / "data" / image);
    }
  }
  return out;
}

// The same for KITTI (images renumbered from 000000, their times kept).
std::string KittiPart(const std::string& out, int first, int last) {
  const std::filesystem::path from(kKitti), to(out);
  std::filesystem::create_directories(to);
  std::filesystem::copy_file(from / "calib.txt", to / "calib.txt");
  std::ifstream times(from / "times.txt");
  std::ofstream part(to / "times.txt");
  std::string time;
  for (int i = 0; std::getline(times, time); ++i) {
    if (i < first || i >= last) continue;
    part << time << "\n";
    for (const char* cam : {"image_0", "image_1"}) {
      std::filesystem::create_directories(to / cam);
      char from_name[16], to_name[16];
      std::snprintf(from_name, sizeof from_name, "%06d.png", i);
      std::snprintf(to_name, sizeof to_name, "%06d.png", i - first);
      std::filesystem::create_symlink(from / cam / from_name, to / cam / to_name);
    }
  }
  return out;
}

// A lab maps a place and comes back: a map of a real recording's first part, extended with a
// later session through the same place. The session is found by localizing its images in the
// map and joins it in the map's frame.
TEST_F(RealDataE2eTest, ALaterEurocSessionLandsWhereTheStillCameraStood) {
  // The MAV stands on the floor until its last second (its ground truth moves by less than 1 mm
  // over frames 21-60, then it lifts off): a session of frames 30-49 must land on the map of the
  // first 20.
  const std::string euroc = dir_.File("euroc_first.db");
  ASSERT_EQ(
      Visloc({"map", "build", "--dataset", kEuroc, "--frames", "20", "--out", euroc}).exit_code, 0);
  const ProcessResult euroc_extend = Visloc(
      {"map", "extend", euroc, "--dataset", EurocPart(dir_.File("euroc_later"), 30, 50), "--json"});
  ASSERT_EQ(euroc_extend.exit_code, 0) << euroc_extend.err;
  EXPECT_EQ(JsonNumber(euroc_extend.out, "session_localization", "localized_frames"), 20);
  EXPECT_EQ(JsonNumber(euroc_extend.out, "session_localization", "agreeing_frames"), 20);
  ASSERT_EQ(Visloc({"map", "export", euroc, "--keyframes", dir_.File("euroc.tum")}).exit_code, 0);
  const Trajectory euroc_keyframes = testing::ReadTumLines(dir_.File("euroc.tum"));
  ASSERT_EQ(euroc_keyframes.size(), 2u);
  EXPECT_TRUE(ApproxEqual(euroc_keyframes[1].pose, euroc_keyframes[0].pose, 0.003, 0.1));
  const ProcessResult localize =
      Visloc({"localize", "--map", euroc, "--dataset", kEuroc, "--frames", "20", "--trajectory",
              dir_.File("e.tum"), "--json"});
  EXPECT_EQ(JsonNumber(localize.out, "localized_fraction"), 1.0);
  EXPECT_LE(Spread(dir_.File("e.tum")).first, 0.005);
  // Another camera's recording is refused before it is mapped, and the map stays as it was.
  const std::string bytes = ReadFileBytes(euroc);
  const ProcessResult other_camera = Visloc({"map", "extend", euroc, "--dataset", kKitti});
  EXPECT_EQ(other_camera.exit_code, 1);
  EXPECT_THAT(other_camera.err, HasSubstr("is not the map's"));
  EXPECT_EQ(ReadFileBytes(euroc), bytes);
}

TEST_F(RealDataE2eTest, ALaterKittiSessionExtendsTheMapDownTheRoad) {
  // KITTI: the car drives on at 0.8 m a frame; the later session (frames 4-10) shares two frames
  // with the map (0-5). Its keyframes land where one build of all eleven frames puts them.
  const std::string kitti = dir_.File("kitti_first.db"), whole = dir_.File("kitti_whole.db");
  ASSERT_EQ(
      Visloc({"map", "build", "--dataset", kKitti, "--frames", "6", "--out", kitti}).exit_code, 0);
  ASSERT_EQ(Visloc({"map", "build", "--dataset", kKitti, "--out", whole}).exit_code, 0);
  const ProcessResult kitti_extend = Visloc(
      {"map", "extend", kitti, "--dataset", KittiPart(dir_.File("kitti_later"), 4, 11), "--json"});
  ASSERT_EQ(kitti_extend.exit_code, 0) << kitti_extend.err;
  EXPECT_GE(JsonNumber(kitti_extend.out, "session_localization", "agreeing_frames"), 5);
  // In the maps' own frames (both the first frame's): each map's level frame is its own estimate.
  for (const auto& [map, out] : {std::pair{kitti, "kitti.tum"}, std::pair{whole, "whole.tum"}}) {
    ASSERT_EQ(
        Visloc({"map", "export", map, "--keyframes", dir_.File(out), "--frame", "map"}).exit_code,
        0);
  }
  const Trajectory extended = testing::ReadTumLines(dir_.File("kitti.tum"));
  const Trajectory reference = ReadTum(dir_.File("whole.tum"));
  ASSERT_EQ(extended.size(), 13u);  // 6 + 7 keyframes.
  double worst_m = 0.0;
  for (size_t k = 6; k < extended.size(); ++k) {
    const auto truth = InterpolateAt(reference, extended[k].timestamp_ns, 1'000'000);
    ASSERT_TRUE(truth.has_value());
    worst_m = std::max(worst_m, (truth->translation - extended[k].pose.translation).norm());
  }
  std::printf("KITTI: the later session's keyframes within %.1f mm of one build of all frames\n",
              1e3 * worst_m);
  EXPECT_LT(worst_m, 0.03);  // Measured 17 mm, 7.5 m from the first frame.
}

// A kidnapped robot's first image: each frame of the recording's second half, alone (no session,
// no prior), through the real server against a map of its first half. The camera rolls and
// turns by up to 30 degrees, and many of these views lie between no two keyframes of the map.
TEST_F(RealDataE2eTest, EachLaterMachineHallImageAloneIsFoundToCentimetres) {
  if (!std::filesystem::is_directory(kMachineHall)) GTEST_SKIP() << "no " << kMachineHall;
  std::filesystem::create_directories(dir_.File("maps"));
  const ProcessResult build = Visloc({"map", "build", "--dataset", kMachineHall, "--frames", "0:75",
                                      "--out", dir_.File("maps/hall.db"), "--json"});
  ASSERT_EQ(build.exit_code, 0) << build.err;
  EXPECT_EQ(JsonNumber(build.out, "frames"), 75);
  ServerProcess server(VISLOC_SERVER_PATH, dir_.File("maps"));
  const std::string found = dir_.File("found.tum");
  const ProcessResult relocalize =
      Visloc({"relocalize", "--server", server.address(), "--map", "hall", "--dataset",
              kMachineHall, "--frames", "75:150", "--trajectory", found, "--json"});
  ASSERT_EQ(relocalize.exit_code, 0) << relocalize.err;
  EXPECT_EQ(JsonNumber(relocalize.out, "frames"), 75);
  const double localized = JsonNumber(relocalize.out, "localized");
  std::printf("Machine Hall: %.0f of 75 later images found alone\n", localized);
  EXPECT_GE(localized, 72);  // 95%; measured 75 (61 with the tracking features and 300 RANSAC
                             // iterations).
  const ProcessResult eval =
      Visloc({"eval", "--gt", kMachineHallTruth, "--gt-origin-first", "--est", found, "--json"});
  ASSERT_EQ(eval.exit_code, 0) << eval.err;
  EXPECT_EQ(JsonNumber(eval.out, "matched_poses"), localized);
  // The first "max" of ATE is its translation's, the first of "rotation_deg" ATE's rotation's.
  EXPECT_LE(JsonNumber(eval.out, "ate", "max"), 0.02);          // Measured 0.70 cm.
  EXPECT_LE(JsonNumber(eval.out, "rotation_deg", "max"), 1.0);  // Measured 0.29 deg.
  // Each stereo pair alone as a rig's frame (issue 56): every one found, verified with both.
  const ProcessResult pairs =
      Visloc({"relocalize", "--server", server.address(), "--map", "hall", "--dataset",
              kMachineHall, "--frames", "75:150", "--cameras", "cam0,cam1", "--trajectory",
              dir_.File("pairs.tum"), "--json"});
  ASSERT_EQ(pairs.exit_code, 0) << pairs.err;
  EXPECT_EQ(JsonNumber(pairs.out, "localized"), 75);
  const ProcessResult pairs_eval = Visloc({"eval", "--gt", kMachineHallTruth, "--gt-origin-first",
                                           "--est", dir_.File("pairs.tum"), "--json"});
  ASSERT_EQ(pairs_eval.exit_code, 0) << pairs_eval.err;
  EXPECT_LE(JsonNumber(pairs_eval.out, "ate", "max"), 0.02);  // Measured 0.70 cm.

  // The same frames as a session: the covariance each reports covers its error against the
  // ground truth (an honest Gaussian: median 1.54 sigma, 2.9% beyond 3).
  const ProcessResult session =
      Visloc({"localize", "--map", dir_.File("maps/hall.db"), "--dataset", kMachineHall, "--frames",
              "75:150", "--trajectory", dir_.File("session.tum"), "--stats",
              dir_.File("session.csv"), "--json"});
  ASSERT_EQ(session.exit_code, 0) << session.err;
  const ProcessResult consistency =
      Visloc({"eval", "--gt", kMachineHallTruth, "--gt-origin-first", "--est",
              dir_.File("session.tum"), "--stats", dir_.File("session.csv"), "--json"});
  ASSERT_EQ(consistency.exit_code, 0) << consistency.err;
  const double median_sigmas = JsonNumber(consistency.out, "normalized_error", "median");
  std::printf("Machine Hall session: error / sigma median %.2f\n", median_sigmas);
  EXPECT_GT(median_sigmas, 1.0);  // Measured 1.89 (4.2 when the fused covariance was reported).
  EXPECT_LT(median_sigmas, 2.0);
  EXPECT_LE(JsonNumber(consistency.out, "consistency", "beyond_3_sigma"), 0.03);  // Measured 0.
  EXPECT_EQ(JsonNumber(consistency.out, "consistency", "beyond_6_sigma"), 0.0);
}

// The on-ramp's ground truth as TUM, and the error of `trajectory` against it: {median share
// of the distance travelled, the last pose's error over the path}.
std::pair<double, double> OnRampDrift(const TempDir& dir, const std::string& trajectory) {
  const std::string truth = dir.File("onramp_truth.tum");
  EXPECT_EQ(Visloc({"dataset", "groundtruth", kOnRamp, "--out", truth}).exit_code, 0);
  return testing::DriftShares(truth, trajectory, dir.File("ends.tum"));
}

// KITTI 01's rig behaves as if its right camera were turned by 0.1 deg: 2.6% of the strong,
// unique stereo matches lie at negative disparities, to -1.1 px, and a map that trusts the
// calibration is 9% too long. The rig's disparity correction estimated from the motion makes it
// metric to about 1%; what is left is a heading that drifts against KITTI's ground truth by 1 deg
// over the 98 deg turn, as much as OpenCV's five-point solver chained over the same frames drifts
// (docs/real-world.md).
TEST_F(RealDataE2eTest, KittiOnRampMapsMetricallyWithTheRigsEstimatedCorrection) {
  if (!std::filesystem::is_directory(kOnRamp)) GTEST_SKIP() << "no " << kOnRamp;
  const ProcessResult build =
      Visloc({"map", "build", "--dataset", kOnRamp, "--out", dir_.File("onramp.db"), "--trajectory",
              dir_.File("onramp.tum"), "--json"});
  ASSERT_EQ(build.exit_code, 0) << build.err;
  EXPECT_EQ(JsonNumber(build.out, "tracking_failures"), 0);
  EXPECT_NEAR(JsonNumber(build.out, "right_camera_yaw_deg"), -0.08, 0.02);  // Measured -0.075.
  const auto [median, end] = OnRampDrift(dir_, dir_.File("onramp.tum"));
  std::printf("KITTI 01: %.2f%% of the distance travelled (median), %.2f%% at the end\n",
              100 * median, 100 * end);
  EXPECT_LT(median, 0.02);  // Measured 1.25% (7.6% trusting the calibration).
  EXPECT_LT(end, 0.02);     // Measured 1.48% (9.2%).
}

// Every other frame (2 m and 5 deg apart) maps, and the frames between localize in that map as a
// sequence: the tracker finds a frame its prediction misses by descriptors alone (was 12 of 26
// frames lost), and a session relocalized without a velocity takes the next strongly supported
// fix 2 m on at once (was 18 of 25 localized, each relocalization waiting a frame).
TEST_F(RealDataE2eTest, KittiEveryOtherFrameMapsAndTheFramesBetweenLocalize) {
  if (!std::filesystem::is_directory(kOnRamp)) GTEST_SKIP() << "no " << kOnRamp;
  const ProcessResult even = Visloc({"map", "build", "--dataset", kOnRamp, "--frames", "0::2",
                                     "--out", dir_.File("even.db"), "--json"});
  ASSERT_EQ(even.exit_code, 0) << even.err;
  EXPECT_EQ(JsonNumber(even.out, "frames"), 26);
  EXPECT_EQ(JsonNumber(even.out, "tracking_failures"), 0);
  const ProcessResult odd =
      Visloc({"localize", "--map", dir_.File("even.db"), "--dataset", kOnRamp, "--frames", "1::2",
              "--trajectory", dir_.File("odd.tum"), "--json"});
  ASSERT_EQ(odd.exit_code, 0) << odd.err;
  EXPECT_EQ(JsonNumber(odd.out, "frames"), 25);
  EXPECT_GE(JsonNumber(odd.out, "localized_fraction") * 25, 23.99);  // Measured 24.
  EXPECT_LT(OnRampDrift(dir_, dir_.File("odd.tum")).first,
            0.03);  // KITTI's two cameras as a rig (issue 56): all 25 frames.
  const ProcessResult rig =
      Visloc({"localize", "--map", dir_.File("even.db"), "--dataset", kOnRamp, "--frames", "1::2",
              "--cameras", "cam0,cam1", "--trajectory", dir_.File("rig.tum"), "--json"});
  ASSERT_EQ(rig.exit_code, 0) << rig.err;
  EXPECT_EQ(JsonNumber(rig.out, "localized_fraction") * 25, 25);
  EXPECT_LT(OnRampDrift(dir_, dir_.File("rig.tum")).first, 0.03);
}

}  // namespace
}  // namespace visloc
