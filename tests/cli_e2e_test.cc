// End-to-end tests of the `visloc` binary: generate sequences with `visloc sim`, evaluate
// trajectories with `visloc eval`, and check the errors users see for bad input.

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <regex>

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
using testing::RunProcess;
using ::testing::StartsWith;
using testing::Visloc;

TEST(CliTest, EveryCommandHasHelpAndUnknownCommandsFail) {
  const ProcessResult top = Visloc({"--help"});
  EXPECT_EQ(top.exit_code, 0);
  for (const char* command : {"sim", "eval"}) {
    EXPECT_THAT(top.out, HasSubstr(command));
    const ProcessResult help = Visloc({command, "--help"});
    EXPECT_EQ(help.exit_code, 0) << command;
    EXPECT_THAT(help.out, StartsWith(std::string("usage: visloc ") + command));
  }
  const ProcessResult unknown = Visloc({"teleport"});
  EXPECT_EQ(unknown.exit_code, 2);
  EXPECT_EQ(unknown.err, "visloc: unknown command 'teleport' (see 'visloc --help')\n");
}

// Both binaries say their version, the same one (CMake's project version, which map files record
// as their builder), and the top-level help names every verb each command has: it listed map as
// "build, info, verify, export, list, delete, rename" long after merge, extend, update, upload
// and download came, and dataset as "(check)".
TEST(CliTest, VersionsAgreeAndTheTopLevelHelpNamesEveryVerb) {
  const ProcessResult client = Visloc({"--version"});
  EXPECT_EQ(client.exit_code, 0);
  const std::regex version_line("visloc (\\d+\\.\\d+\\.\\d+)\n");
  std::smatch client_version;
  ASSERT_TRUE(std::regex_match(client.out, client_version, version_line)) << client.out;
  const ProcessResult server = testing::RunProcess({VISLOC_SERVER_PATH, "--version"});
  EXPECT_EQ(server.exit_code, 0);
  EXPECT_EQ(server.out, "visloc-server " + client_version[1].str() + "\n");

  const std::string help = Visloc({"--help"}).out;
  for (const std::string command : {"map", "dataset"}) {
    const size_t line_start = help.find("\n  " + command + " ");
    ASSERT_NE(line_start, std::string::npos) << command;
    // The command's summary, up to the next command's line.
    const std::string summary =
        help.substr(line_start, help.find("\n  ", line_start + 1) - line_start);
    const std::string verbs = Visloc({command, "--help"}).out;
    const std::regex verb_line("\n  ([a-z]+) +");
    for (auto it = std::sregex_iterator(verbs.begin(), verbs.end(), verb_line);
         it != std::sregex_iterator(); ++it) {
      EXPECT_THAT(summary, HasSubstr((*it)[1].str())) << "visloc --help's " << command << " line";
    }
  }
}

TEST(CliTest, SimWritesSequencesThatEvalScoresExactly) {
  TempDir dir;
  const ProcessResult sim =
      Visloc({"sim", "--out", dir.path(), "--sequence", "kidnap,straight", "--frames", "12",
              "--resolution", "160x120", "--supersample", "1", "--json"});
  ASSERT_EQ(sim.exit_code, 0) << sim.err;
  EXPECT_THAT(sim.out, HasSubstr("\"name\":\"kidnap\""));
  EXPECT_THAT(sim.out, HasSubstr("\"frames\":12"));
  const Dataset dataset = ReadDataset(dir.path() + "/kidnap");
  EXPECT_EQ(dataset.frames.size(), 12u);
  EXPECT_EQ(dataset.left.camera.width(), 160);

  // Ground truth against itself: every error is zero and every frame is covered.
  const std::string gt = dir.path() + "/kidnap/groundtruth_map.tum";
  const ProcessResult self = Visloc({"eval", "--gt", gt, "--est", gt, "--align", "--json"});
  ASSERT_EQ(self.exit_code, 0) << self.err;
  EXPECT_DOUBLE_EQ(JsonNumber(self.out, "ate", "rmse"), 0.0);
  EXPECT_NEAR(JsonNumber(self.out, "ate_aligned", "max"), 0.0, 1e-9);
  EXPECT_DOUBLE_EQ(JsonNumber(self.out, "coverage", "coverage"), 1.0);

  // A known 3 cm offset of every pose comes out as exactly 3 cm, and alignment removes it.
  Trajectory shifted = ReadTum(gt);
  for (StampedPose& pose : shifted) pose.pose.translation += Eigen::Vector3d(0.0, 0.03, 0.0);
  shifted.erase(shifted.begin() + 6, shifted.end());  // half the frames "not localized"
  WriteTum(dir.File("shifted.tum"), shifted);
  const ProcessResult offset =
      Visloc({"eval", "--gt", gt, "--est", dir.File("shifted.tum"), "--align", "--json"});
  ASSERT_EQ(offset.exit_code, 0) << offset.err;
  EXPECT_NEAR(JsonNumber(offset.out, "ate", "rmse"), 0.03, 1e-8);
  EXPECT_NEAR(JsonNumber(offset.out, "ate", "max"), 0.03, 1e-8);
  EXPECT_NEAR(JsonNumber(offset.out, "ate_aligned", "max"), 0.0, 1e-8);
  EXPECT_NEAR(JsonNumber(offset.out, "coverage", "coverage"), 0.5, 1e-12);

  const ProcessResult human = Visloc({"eval", "--gt", gt, "--est", dir.File("shifted.tum")});
  EXPECT_EQ(human.exit_code, 0);
  EXPECT_THAT(human.out, HasSubstr("coverage 50.0%"));
  EXPECT_THAT(human.out, HasSubstr("rmse   3.0000"));
}

TEST(CliTest, BadInputGetsOneLineErrorsAndNonZeroExit) {
  TempDir dir;
  std::ofstream(dir.File("bad.tum")) << "1.0 0 0 0 0 0 0 1\n2.0 zero 0 0 0 0 0 1\n";
  std::ofstream(dir.File("good.tum")) << "1.0 0 0 0 0 0 0 1\n";
  const struct {
    std::vector<std::string> args;
    int exit_code;
    std::string error;
  } cases[] = {
      {{"eval", "--est", "x.tum"}, 2, "visloc eval: missing --gt (see 'visloc eval --help')\n"},
      {{"eval", "--gt", dir.File("missing.tum"), "--est", dir.File("good.tum")},
       1,
       "visloc eval: " + dir.File("missing.tum") + ": cannot open file\n"},
      {{"eval", "--gt", dir.File("good.tum"), "--est", dir.File("bad.tum")},
       1,
       "visloc eval: " + dir.File("bad.tum") + ":2: field 2 is not a number: 'zero'\n"},
      {{"sim", "--out", dir.path(), "--sequence", "moon"},
       1,
       "visloc sim: unknown sequence 'moon' (known: map_square, query_square, straight, circle, "
       "outward, glances, kidnap, blankwall, lowlight, occluders, changed, outofmap, map_suite, "
       "query_suite, drive, map_building)\n"},
      {{"sim", "--out", dir.path(), "--resolution", "big"},
       2,
       "visloc sim: --resolution expects WIDTHxHEIGHT between 16 and 4096, got 'big' (see 'visloc "
       "sim --help')\n"},
      {{"sim", "--out", dir.path(), "--format", "kitti", "--distortion"},
       2,
       "visloc sim: KITTI sequences are rectified: --distortion needs --format euroc (see 'visloc "
       "sim --help')\n"},
      // The help that lists the missing flag is the verb's, not the command's.
      {{"map", "build", "--out", dir.File("m.db")},
       2,
       "visloc map build: missing --dataset (see 'visloc map build --help')\n"},
      {{"stream", "--server", "127.0.0.1:1", "--map", "m", "--dataset", dir.path(), "--camera", "0",
        "--camera-yaml", dir.File("sensor.yaml")},
       2,
       "visloc stream: give --dataset DIR or --camera SOURCE, not both (see 'visloc stream "
       "--help')\n"},
  };
  for (const auto& c : cases) {
    const ProcessResult result = Visloc(c.args);
    EXPECT_EQ(result.exit_code, c.exit_code) << c.args[0] << " " << c.args[1];
    EXPECT_EQ(result.err, c.error);
    EXPECT_EQ(result.out, "");
  }
}

TEST(CliTest, SimListsTheCatalogue) {
  const ProcessResult list = Visloc({"sim", "--list"});
  EXPECT_EQ(list.exit_code, 0);
  EXPECT_THAT(list.out, HasSubstr("kidnap"));
  EXPECT_THAT(list.out, HasSubstr("outofmap"));
}

TEST(CliTest, PlotCurvesDrawsEachColumnAgainstTheFirst) {
  TempDir dir("visloc-curves");
  std::ofstream(dir.File("scaling.csv")) << "keyframes,relocalization_ms,memory_MiB\n"
                                         << "100,1.5,0.5\n1000,1.9,4.9\n10000,2.4,49\n";
  const ProcessResult plot =
      Visloc({"plot", "--curves", dir.File("scaling.csv"), "--log-x", "--out", dir.File("s.svg")});
  ASSERT_EQ(plot.exit_code, 0) << plot.err;
  EXPECT_THAT(plot.out, HasSubstr("2 curves of 3 points"));
  const std::string text = ReadFileBytes(dir.File("s.svg"));
  EXPECT_THAT(text, HasSubstr("relocalization_ms"));
  EXPECT_THAT(text, HasSubstr("10000: 49.00"));
  EXPECT_THAT(text, HasSubstr("keyframes (log scale)"));

  std::ofstream(dir.File("bad.csv")) << "keyframes,ms\n100,fast\n";
  const ProcessResult bad =
      Visloc({"plot", "--curves", dir.File("bad.csv"), "--out", dir.File("b.svg")});
  EXPECT_EQ(bad.exit_code, 1);
  EXPECT_THAT(bad.err, HasSubstr("bad.csv:2: not a number: 'fast'"));
}

}  // namespace
}  // namespace visloc
