// End-to-end localization: maps from `visloc map build`, sequences from `visloc sim`, the
// engine run by `visloc localize`, and accuracy measured by `visloc eval` against the
// simulator's exact ground truth. The shared data comes from the localization_data fixture
// (tests/support/make_localization_data.sh): a map of the 2 m square and short queries.
// Targets are issue 5's; the comments give what the full-length runs measure.

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <sstream>

#include "core/util/temp_dir.h"
#include "core/util/text_file.h"
#include "dataset/dataset.h"
#include "dataset/euroc.h"
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

struct LocalizeRun {
  std::string summary_json;  // visloc localize --json
  std::string eval_json;     // visloc eval --json of the trajectory against ground truth
  std::vector<std::vector<std::string>> stats;  // CSV rows (header dropped)
  Trajectory trajectory;
  double localized_fraction() const { return JsonNumber(summary_json, "", "localized_fraction"); }
  double coverage() const { return JsonNumber(eval_json, "", "coverage"); }
  double median_m() const { return JsonNumber(eval_json, "translation_m", "median"); }
  double max_m() const { return JsonNumber(eval_json, "translation_m", "max"); }
  double median_deg() const { return JsonNumber(eval_json, "rotation_deg", "median"); }
  // The position errors in units of the per-axis sigma each frame reported (eval --stats).
  double median_sigmas() const { return JsonNumber(eval_json, "normalized_error", "median"); }
  double beyond_3_sigma() const { return JsonNumber(eval_json, "consistency", "beyond_3_sigma"); }
  double beyond_6_sigma() const { return JsonNumber(eval_json, "consistency", "beyond_6_sigma"); }
};

LocalizeRun Localize(const std::string& sequence, std::vector<std::string> extra = {}) {
  TempDir dir("visloc_localization_e2e");
  const std::string trajectory = dir.File("est.tum"), stats = dir.File("stats.csv");
  std::vector<std::string> args = {
      "localize",     "--map",    kData + "/map.db", "--dataset", kData + "/" + sequence,
      "--trajectory", trajectory, "--stats",         stats,       "--json"};
  args.insert(args.end(), extra.begin(), extra.end());
  const ProcessResult localize = Visloc(args);
  EXPECT_EQ(localize.exit_code, 0) << localize.err;
  LocalizeRun run;
  run.summary_json = localize.out;
  run.trajectory = ReadTum(trajectory);
  const std::string gt = kData + "/" + sequence + "/groundtruth_map.tum";
  if (!run.trajectory.empty()) {
    const ProcessResult eval =
        Visloc({"eval", "--gt", gt, "--est", trajectory, "--stats", stats, "--json"});
    EXPECT_EQ(eval.exit_code, 0) << eval.err;
    run.eval_json = eval.out;
  }
  for (const TextLine& line : ReadTextLines(stats)) {
    if (line.number == 1) continue;
    std::vector<std::string> fields;
    std::stringstream in(line.text);
    for (std::string field; std::getline(in, field, ',');) fields.push_back(field);
    run.stats.push_back(fields);
  }
  std::string label = sequence;
  for (const std::string& arg : extra) label += " " + arg;
  std::printf("%s: localized %.3f, median %.2f cm / %.3f deg, max %.2f cm\n", label.c_str(),
              run.localized_fraction(), run.eval_json.empty() ? 0 : 100 * run.median_m(),
              run.eval_json.empty() ? 0 : run.median_deg(),
              run.eval_json.empty() ? 0 : 100 * run.max_m());
  return run;
}

std::vector<int> CoveredFrames(const std::string& sequence) {
  std::ifstream in(kData + "/" + sequence + "/sequence.json");
  const std::string json((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::smatch list = [&] {
    std::smatch m;
    std::regex_search(json, m, std::regex("\"covered_frames\":\\[([0-9,]*)\\]"));
    return m;
  }();
  std::vector<int> frames;
  std::stringstream items(list[1].str());
  for (std::string item; std::getline(items, item, ',');) frames.push_back(std::stoi(item));
  return frames;
}

TEST(LocalizationE2eTest, OffsetSquareIsLocalizedToCentimetres) {
  const LocalizeRun run = Localize("query_square");
  EXPECT_GE(run.localized_fraction(), 0.99);
  EXPECT_GE(run.coverage(), 0.99);
  EXPECT_LE(run.median_m(), 0.02);   // measured 0.41 cm
  EXPECT_LE(run.median_deg(), 0.3);  // measured 0.04 deg
  // Every row carries the statistics product.md promises.
  ASSERT_EQ(run.stats.size(), 120u);
  const std::vector<std::string>& row = run.stats.back();
  EXPECT_EQ(row[1], "tracking");
  EXPECT_GT(std::stoi(row[3]), 100);  // features
  EXPECT_GT(std::stoi(row[4]), 100);  // predicted visible
  EXPECT_GT(std::stoi(row[6]), 50);   // inliers
  EXPECT_GT(std::stod(row[7]), 0.5);  // inlier ratio
}

// A robot whose camera is not the mapping rig's: the square walked with a 640x480 camera of the
// same field of view, in the map made at 320x240. Its images are resampled to the map camera's
// focal length before detection; described at their own pixels, the corners matched the map's
// at other scales (56% inliers, 1.6 cm median and 10 cm max error over 150 frames).
TEST(LocalizationE2eTest, ACameraOfAnotherResolutionTracksAsTheMapsOwnDoes) {
  TempDir dir("visloc_localization_e2e");
  const ProcessResult sim =
      Visloc({"sim", "--out", dir.path(), "--sequence", "query_square", "--resolution", "640x480",
              "--frames", "60", "--no-contact-sheet"});
  ASSERT_EQ(sim.exit_code, 0) << sim.err;
  const std::string sequence = dir.path() + "/query_square";
  const ProcessResult localize = Visloc({"localize", "--map", kData + "/map.db", "--dataset",
                                         sequence, "--trajectory", dir.File("est.tum"), "--json"});
  ASSERT_EQ(localize.exit_code, 0) << localize.err;
  const ProcessResult eval = Visloc(
      {"eval", "--gt", sequence + "/groundtruth_map.tum", "--est", dir.File("est.tum"), "--json"});
  ASSERT_EQ(eval.exit_code, 0) << eval.err;
  const double median_m = JsonNumber(eval.out, "translation_m", "median");
  const double max_m = JsonNumber(eval.out, "translation_m", "max");
  const double inlier_ratio = JsonNumber(localize.out, "", "inlier_ratio_median");
  std::printf("640x480 in the 320x240 map: median %.2f cm, max %.2f cm, inlier ratio %.2f\n",
              100 * median_m, 100 * max_m, inlier_ratio);
  EXPECT_EQ(JsonNumber(localize.out, "", "localized_fraction"), 1.0);
  EXPECT_LT(median_m, 0.006);  // measured 0.32 cm over 150 frames
  EXPECT_LT(max_m, 0.02);
  EXPECT_GT(inlier_ratio, 0.8);
}

TEST(LocalizationE2eTest, StraightLineLeavingTheMap) {
  const LocalizeRun run = Localize("straight");
  EXPECT_GE(run.localized_fraction(), 0.95);
  EXPECT_LE(run.max_m(), 0.15);  // measured 1.3 cm
}

// A platform much faster than the walking robot the motion model expects (a car): every 30th
// frame of the straight line, played at 15 fps, moves 0.44 m a frame. The second frame's fix is
// far from a prior that knows no velocity yet; strongly supported by tracking, it is taken at
// once (reported relocalized) and its motion becomes the velocity, so the rest track. Before,
// every frame after a fix was held back as a jump and the session alternated lost/relocalized.
TEST(LocalizationE2eTest, AFastPlatformTracksFromItsSecondFrame) {
  TempDir dir("visloc_fast");
  const Dataset walk = ReadDataset(kData + "/straight");
  EurocWriter writer(dir.File("fast"), walk.left, walk.right);
  Trajectory truth;
  const Trajectory walk_truth = ReadTum(kData + "/straight/groundtruth_map.tum");
  // The first 150 frames: the rest leave the mapped area.
  for (size_t i = 0, k = 0; i < 150; i += 30, ++k) {
    const int64_t stamp = walk.frames[0].timestamp_ns + static_cast<int64_t>(k) * 66'666'667;
    const int w = walk.left.camera.width(), h = walk.left.camera.height();
    writer.AddFrame(stamp, LoadGreyImage(walk.frames[i].left_path, w, h),
                    LoadGreyImage(walk.frames[i].right_path, w, h));
    truth.push_back({stamp, walk_truth[i].pose});
  }
  writer.Finish({}, {}, {});
  WriteTum(dir.File("fast/groundtruth_map.tum"), truth);
  const ProcessResult run =
      Visloc({"localize", "--map", kData + "/map.db", "--dataset", dir.File("fast"), "--trajectory",
              dir.File("est.tum"), "--json"});
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_EQ(JsonNumber(run.out, "localized_fraction"), 1.0);
  EXPECT_EQ(JsonNumber(run.out, "statuses", "relocalized"), 2);
  EXPECT_EQ(JsonNumber(run.out, "statuses", "tracking"), static_cast<double>(truth.size() - 2));
  const ProcessResult eval = Visloc({"eval", "--gt", dir.File("fast/groundtruth_map.tum"), "--est",
                                     dir.File("est.tum"), "--json"});
  EXPECT_LT(JsonNumber(eval.out, "translation_m", "max"), 0.03);
}

TEST(LocalizationE2eTest, CircleWithNewViewingDirections) {
  const LocalizeRun run = Localize("circle");
  EXPECT_GE(run.localized_fraction(), 0.90);
  EXPECT_LE(run.median_m(), 0.05);  // measured 0.55 cm
}

TEST(LocalizationE2eTest, LowLightAndMovingOccluders) {
  EXPECT_GE(Localize("lowlight").localized_fraction(), 0.95);
  EXPECT_GE(Localize("occluders").localized_fraction(), 0.95);
}

// A robot fuses these poses in its own filter: a pose that is confidently wrong is worse than none.
// The position error in units of the covariance each frame reported (the Mahalanobis distance)
// must be within 3 for 97% of the frames and within 6 for all (an honest Gaussian: median 1.54,
// 2.9% beyond 3). The fused covariance once claimed a millimetre where the map itself is off by
// several: 29% of the square's frames lay beyond 3 sigma, 3% of the straight line's beyond 6.
// Facing out of the mapped square (outward) and glancing over the shoulder (glances) the frame
// sees the map's points from where the mapping run never looked; before the covariance counted
// the points' own uncertainty, 11.7% of the outward walk lay beyond 3 sigma, up to 4.8.
TEST(LocalizationE2eTest, TheReportedCovarianceCoversTheError) {
  for (const char* sequence : {"query_square", "straight", "circle", "outward", "glances"}) {
    const LocalizeRun run = Localize(sequence);
    std::printf("%s: error / sigma median %.2f, %.1f%% beyond 3, %.1f%% beyond 6\n", sequence,
                run.median_sigmas(), 100 * run.beyond_3_sigma(), 100 * run.beyond_6_sigma());
    EXPECT_LE(run.beyond_3_sigma(), 0.03) << sequence;
    EXPECT_EQ(run.beyond_6_sigma(), 0.0) << sequence;
    // And not inflated to get there: the fixture's map says its rig is exact (--rig-error 0,0),
    // so the covariance leaves out a real rig's calibration error. With it, as for a map that
    // does not say, the median was 0.63-0.77 of maps then (below). Measured: 1.00-1.45 then.
    // Since the map builder of 4e2622b-b08a3ae (refinement, end adjustment, loop correction) its
    // maps of these rooms are twice as accurate (the mapping square: 0.40 cm rms against 0.73),
    // while the mapping's share of the covariance (PoseTrackerOptions::map_error_px,
    // map_drift_fraction) was measured on the old maps: the median is 0.68-0.96 now. Lowering that
    // share alone (0.0015 of the distance to 0.0003) brings it back to 0.94-1.19 but turns the
    // points' share the larger one on walks facing out of the map, which the `limited` rule and the
    // localizability prediction read; calibrating the two together is open (issue 58's note).
    EXPECT_GE(run.median_sigmas(), 0.65) << sequence;
    EXPECT_LE(run.median_sigmas(), 2.0) << sequence;
  }
}

// A fix whose covariance is mostly its points' own uncertainty (the map saw them from elsewhere)
// is reported limited, not tracking: facing out of the mapped square, measured 42% of the frames;
// walking the square as the mapping run did, none.
TEST(LocalizationE2eTest, FixesLeaningOnPointsTheMapSawFromElsewhereAreLimited) {
  const auto limited_share = [](const LocalizeRun& run) {
    size_t limited = 0;
    for (const auto& row : run.stats) limited += row[1] == "limited";
    return static_cast<double>(limited) / static_cast<double>(std::max<size_t>(1, run.stats.size()));
  };
  const LocalizeRun outward = Localize("outward");
  EXPECT_EQ(outward.localized_fraction(), 1.0);
  EXPECT_GE(limited_share(outward), 0.2);
  EXPECT_LE(limited_share(outward), 0.8);
  EXPECT_EQ(limited_share(Localize("query_square")), 0.0);
}

TEST(LocalizationE2eTest, OutOfMapImagesAreNeverLocalized) {
  const LocalizeRun run = Localize("outofmap");
  EXPECT_EQ(run.localized_fraction(), 0.0);
  EXPECT_TRUE(run.trajectory.empty());
  for (const auto& row : run.stats) EXPECT_EQ(row[1], "initializing");
}

// `visloc relocalize --evidence`: every candidate of both feature passes, verified under no rule,
// one TSV row each. Views of the map have a candidate at their true pose far above the
// significance the acceptance rule asks (40); images of another room have none near it.
std::vector<std::map<std::string, std::string>> RelocalizationEvidence(const std::string& sequence,
                                                                       const std::string& frames) {
  TempDir dir("visloc_evidence_e2e");
  const std::string tsv = dir.File("evidence.tsv");
  const ProcessResult run =
      Visloc({"relocalize", "--map-file", kData + "/map.db", "--dataset", kData + "/" + sequence,
              "--frames", frames, "--evidence", tsv, "--json"});
  EXPECT_EQ(run.exit_code, 0) << run.err;
  std::vector<std::map<std::string, std::string>> rows;
  std::vector<std::string> header;
  for (const TextLine& line : ReadTextLines(tsv)) {
    std::vector<std::string> fields;
    std::stringstream in(line.text);
    for (std::string field; std::getline(in, field, '\t');) fields.push_back(field);
    if (line.number == 1) {
      header = fields;
      continue;
    }
    EXPECT_EQ(fields.size(), header.size()) << line.text;
    std::map<std::string, std::string> row;
    for (size_t i = 0; i < std::min(fields.size(), header.size()); ++i) row[header[i]] = fields[i];
    rows.push_back(row);
  }
  EXPECT_EQ(JsonNumber(run.out, "rows"), static_cast<double>(rows.size()));
  return rows;
}

TEST(LocalizationE2eTest, RelocalizationEvidenceSeparatesViewsOfTheMapFromAnotherRoom) {
  const auto views = RelocalizationEvidence("query_square", "0:60:20");
  const Dataset query = ReadDataset(kData + "/query_square");
  const Trajectory gt = ReadTum(kData + "/query_square/groundtruth_map.tum");
  for (int frame : {0, 1, 2}) {
    double best_significance = 0, best_error_m = 1e9;
    std::set<std::string> passes;
    for (const auto& row : views) {
      if (std::stoi(row.at("frame")) != frame) continue;
      passes.insert(row.at("pass"));
      if (row.at("verified") != "1" || std::stod(row.at("significance")) <= best_significance) {
        continue;
      }
      best_significance = std::stod(row.at("significance"));
      const auto truth = InterpolateAt(gt, std::stoll(row.at("timestamp_ns")), 1'000'000);
      ASSERT_TRUE(truth.has_value());
      best_error_m = (truth->translation - Eigen::Vector3d(std::stod(row.at("tx")),
                                                           std::stod(row.at("ty")),
                                                           std::stod(row.at("tz"))))
                         .norm();
    }
    EXPECT_EQ(passes, (std::set<std::string>{"1", "2"})) << frame;
    EXPECT_GT(best_significance, 80.0) << frame;
    EXPECT_LT(best_error_m, 0.02) << frame;
  }
  double strongest_elsewhere = 0;
  for (const auto& row : RelocalizationEvidence("outofmap", "0:60:10")) {
    if (row.at("verified") == "1") {
      strongest_elsewhere = std::max(strongest_elsewhere, std::stod(row.at("significance")));
    }
  }
  std::printf("evidence: strongest candidate in another room, significance %.1f\n",
              strongest_elsewhere);
  EXPECT_LT(strongest_elsewhere, 40.0);
}

TEST(LocalizationE2eTest, KidnappedRobotIsLostWhileCoveredAndRelocalizedAfter) {
  const std::vector<int> covered = CoveredFrames("kidnap");
  ASSERT_GE(covered.size(), 10u);
  const LocalizeRun run = Localize("kidnap");
  ASSERT_EQ(run.stats.size(), 150u);
  for (int k : covered) EXPECT_EQ(run.stats[k][1], "lost") << "covered frame " << k;
  const int returned = covered.back() + 1;
  int relocalized_at = -1;
  for (int k = returned; k < returned + 3 && relocalized_at < 0; ++k) {
    if (run.stats[k][1] == "relocalized") relocalized_at = k;
  }
  ASSERT_GE(relocalized_at, 0) << "not relocalized within 3 frames of frame " << returned;
  EXPECT_EQ(run.stats[relocalized_at][2], "relocalization");
  // After the kidnapping: every frame has a pose within 5 cm of the truth.
  const Trajectory gt = ReadTum(kData + "/kidnap/groundtruth_map.tum");
  const int64_t after_ns = std::stoll(run.stats[relocalized_at][0]);
  double worst_m = 0;
  int compared = 0;
  for (const StampedPose& est : run.trajectory) {
    if (est.timestamp_ns < after_ns) continue;
    const auto truth = InterpolateAt(gt, est.timestamp_ns, 100'000'000);
    ASSERT_TRUE(truth.has_value());
    worst_m = std::max(worst_m, (truth->translation - est.pose.translation).norm());
    ++compared;
  }
  EXPECT_EQ(compared, 150 - relocalized_at);
  EXPECT_LE(worst_m, 0.05);  // measured 1.0 cm
}

TEST(LocalizationE2eTest, OdometryAndGyroBridgeTwoSecondsWithoutVision) {
  // Camera blacked out from 3 s to 5 s while the robot walks on.
  const LocalizeRun fused = Localize("query_square", {"--odometry", "--blackout", "3,2", "--gt",
                                                      kData + "/query_square/groundtruth_map.tum"});
  const LocalizeRun coasting =
      Localize("query_square", {"--bridge-constant-velocity", "--blackout", "3,2", "--gt",
                                kData + "/query_square/groundtruth_map.tum"});
  const double fused_max = JsonNumber(fused.summary_json, "ground_truth", "bridged_position_max_m");
  const double coasting_max =
      JsonNumber(coasting.summary_json, "ground_truth", "bridged_position_max_m");
  std::printf("2 s without vision: odometry + gyro max %.2f cm, constant velocity max %.2f cm\n",
              100 * fused_max, 100 * coasting_max);
  EXPECT_GE(JsonNumber(fused.summary_json, "ground_truth", "bridged_compared"), 29);
  EXPECT_EQ(JsonNumber(fused.summary_json, "", "posed_fraction"), 1.0);
  EXPECT_LE(fused_max, 0.05);
  EXPECT_LT(fused_max, coasting_max);
  for (const auto& row : fused.stats) {
    if (row[2] == "motion") {
      EXPECT_EQ(row[1], "limited");
    }
  }
  // Without odometry the same frames are lost: no invented pose.
  const LocalizeRun vision = Localize("query_square", {"--blackout", "3,2"});
  EXPECT_LE(vision.localized_fraction(), 1.0 - 29.0 / 120);
  EXPECT_GE(vision.localized_fraction(), 1.0 - 31.0 / 120);
}

// Median of one integer column of the stats CSV.
int MedianColumn(const LocalizeRun& run, size_t column) {
  std::vector<int> values;
  for (const auto& row : run.stats) values.push_back(std::stoi(row[column]));
  std::sort(values.begin(), values.end());
  return values.empty() ? 0 : values[values.size() / 2];
}

TEST(LocalizationE2eTest, BaselinesLocalizeTooButPredictMorePoints) {
  const LocalizeRun visibility = Localize("query_square", {"--frames", "40"});
  const LocalizeRun transparent =
      Localize("query_square", {"--mode", "transparent", "--frames", "40"});
  const LocalizeRun brute = Localize("query_square", {"--mode", "brute_force", "--frames", "40"});
  EXPECT_GE(transparent.localized_fraction(), 0.95);
  EXPECT_GE(brute.localized_fraction(), 0.95);
  EXPECT_LE(transparent.median_m(), 0.02);
  EXPECT_LE(brute.median_m(), 0.02);
  // Column 4: points predicted visible. The learned visibility predicts far fewer.
  const int predicted = MedianColumn(visibility, 4), all_in_view = MedianColumn(transparent, 4);
  std::printf("predicted visible, median: visibility %d, transparent world %d\n", predicted,
              all_in_view);
  EXPECT_LT(1.5 * predicted, all_in_view);
}

TEST(LocalizationE2eTest, PlotShowsTheTrajectoryAndTheKidnappingJump) {
  TempDir dir("visloc_plot_e2e");
  const ProcessResult localize =
      Visloc({"localize", "--map", kData + "/map.db", "--dataset", kData + "/kidnap",
              "--trajectory", dir.File("est.tum"), "--stats", dir.File("stats.csv")});
  ASSERT_EQ(localize.exit_code, 0) << localize.err;
  for (const std::string name : {"plot.png", "plot.svg"}) {
    const ProcessResult plot =
        Visloc({"plot", "--map", kData + "/map.db", "--trajectory", dir.File("est.tum"), "--stats",
                dir.File("stats.csv"), "--gt", kData + "/kidnap/groundtruth_map.tum", "--out",
                dir.File(name)});
    ASSERT_EQ(plot.exit_code, 0) << plot.err;
    // 132 posed frames: 130 segments along the walk and one dashed jump across the kidnapping.
    EXPECT_THAT(plot.out, HasSubstr("130 trajectory segments, 1 gaps"));
  }
  std::ifstream svg(dir.File("plot.svg"));
  const std::string text((std::istreambuf_iterator<char>(svg)), std::istreambuf_iterator<char>());
  EXPECT_THAT(text, HasSubstr("<svg"));
  EXPECT_THAT(text, HasSubstr("stroke-dasharray"));
  std::ifstream png(dir.File("plot.png"), std::ios::binary);
  char signature[8] = {};
  png.read(signature, 8);
  EXPECT_EQ(std::string(signature + 1, 3), "PNG");
  const ProcessResult series = Visloc(
      {"plot", "--series", "--stats", dir.File("stats.csv"), "--out", dir.File("series.svg")});
  ASSERT_EQ(series.exit_code, 0) << series.err;
  EXPECT_THAT(series.out, HasSubstr("150 frames"));
  std::ifstream series_svg(dir.File("series.svg"));
  const std::string series_text((std::istreambuf_iterator<char>(series_svg)),
                                std::istreambuf_iterator<char>());
  EXPECT_THAT(series_text, HasSubstr("RANSAC iterations"));
  const ProcessResult no_stats = Visloc({"plot", "--series", "--out", dir.File("s.png")});
  EXPECT_EQ(no_stats.exit_code, 2);
  EXPECT_THAT(no_stats.err, HasSubstr("--series needs --stats"));
  const ProcessResult wrong = Visloc({"plot", "--map", kData + "/map.db", "--trajectory",
                                      dir.File("est.tum"), "--out", dir.File("plot.gif")});
  EXPECT_EQ(wrong.exit_code, 1);
  EXPECT_THAT(wrong.err, HasSubstr("the plot must be .png or .svg"));
}

TEST(LocalizationE2eTest, BenchReportsEveryFigureInOneRun) {
  const ProcessResult bench =
      Visloc({"bench", "--dataset", kData + "/query_square", "--map", kData + "/map.db", "--frames",
              "20", "--relocalization-queries", "4", "--json"});
  ASSERT_EQ(bench.exit_code, 0) << bench.err;
  for (const char* key :
       {"ms_per_frame_median", "ms_per_frame_p95", "no_visibility_ms_per_frame_median",
        "brute_force_ms_per_frame_median", "orb_reference_ms_per_frame_median",
        "relocalization_ms_median", "map_search_ms_median", "no_visibility_map_search_ms_median"}) {
    EXPECT_GT(JsonNumber(bench.out, "", key), 0.0) << key;
  }
  EXPECT_EQ(JsonNumber(bench.out, "", "localized_fraction"), 1.0);
  EXPECT_EQ(JsonNumber(bench.out, "", "relocalization_found_fraction"), 1.0);
  // The same queries with the full features alone, interleaved; the share the tracking features
  // did not find.
  EXPECT_EQ(JsonNumber(bench.out, "", "relocalization_full_features_found_fraction"), 1.0);
  EXPECT_GT(JsonNumber(bench.out, "", "relocalization_full_features_ms_median"), 0.0);
  const double second = JsonNumber(bench.out, "", "relocalization_second_pass_fraction");
  EXPECT_TRUE(second >= 0.0 && second <= 1.0) << second;
  // Ratios within one run: brute force matches every keypoint against every map point.
  EXPECT_GT(JsonNumber(bench.out, "", "brute_force_ms_per_frame_median"),
            JsonNumber(bench.out, "", "ms_per_frame_median"));
  EXPECT_GT(JsonNumber(bench.out, "detect", "median"), 0.0);
  // Relocalization's steps apart, each timed and all of them within the whole (medians of four
  // queries: their sum may pass the median whole a little).
  double steps_ms = 0.0;
  for (const char* step : {"features", "retrieval", "matching", "ransac", "verification"}) {
    const double ms = JsonNumber(bench.out, step, "median");
    EXPECT_GT(ms, 0.0) << step;
    steps_ms += ms;
  }
  EXPECT_LE(steps_ms, 1.2 * JsonNumber(bench.out, "", "relocalization_ms_median"));
}

TEST(LocalizationE2eTest, MaxFeaturesCapsTheKeypointsPerQuery) {
  const LocalizeRun capped = Localize("query_square", {"--frames", "20", "--max-features", "150"});
  EXPECT_EQ(capped.localized_fraction(), 1.0);
  for (const auto& row : capped.stats) EXPECT_LE(std::stoi(row[3]), 150);  // Column 3: features.
  const LocalizeRun full = Localize("query_square", {"--frames", "20"});
  EXPECT_GT(MedianColumn(full, 3), 150);
  // Sessions detect at the map's finest scale only; --all-scales uses all three, as the map
  // builder does, and finds at least as many corners to choose from.
  const LocalizeRun all_scales = Localize("query_square", {"--frames", "20", "--all-scales"});
  EXPECT_EQ(all_scales.localized_fraction(), 1.0);
  EXPECT_GE(MedianColumn(all_scales, 3), MedianColumn(full, 3));
}

TEST(LocalizationE2eTest, BadArgumentsAreNamed) {
  const ProcessResult no_map =
      Visloc({"localize", "--map", kData + "/nope.db", "--dataset", kData + "/query_square"});
  EXPECT_EQ(no_map.exit_code, 1);
  EXPECT_THAT(no_map.err, HasSubstr("nope.db"));
  const ProcessResult mode = Visloc({"localize", "--map", kData + "/map.db", "--dataset",
                                     kData + "/query_square", "--mode", "magic"});
  EXPECT_EQ(mode.exit_code, 1);
  EXPECT_THAT(mode.err, HasSubstr("unknown prediction mode 'magic'"));
  const ProcessResult blackout = Visloc({"localize", "--map", kData + "/map.db", "--dataset",
                                         kData + "/query_square", "--blackout", "3"});
  EXPECT_EQ(blackout.exit_code, 2);
  EXPECT_THAT(blackout.err, HasSubstr("--blackout wants START,DURATION"));
}

}  // namespace
}  // namespace visloc
