// A mapping job outlives its server. `visloc map build --server` streams the fixture's stereo run
// to the real visloc-server, which is killed with SIGKILL at a random moment of the job (while
// frames arrive, while it finishes, while it publishes) and started again on the same folder and
// port. Every run must end with the map an unbroken run makes (keyframes within 1 mm), and the
// map of that name that was there must stay whole until the new one replaces it.
//
// $VISLOC_KILL_RUNS sets the number of kills (2 by default, for CI; scripts/mapping-kill.sh runs
// 20), half of them while frames arrive and half after MappingEnd, and $VISLOC_KILL_SEED their
// moments. Each run prints one line "kill-run ..." for the script.

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <thread>

#include "core/util/temp_dir.h"
#include "core/util/text_file.h"
#include "tests/support/e2e.h"
#include "tests/support/process.h"

namespace visloc {
namespace {

using ::testing::HasSubstr;
using testing::JsonNumber;
using testing::ProcessResult;
using testing::ServerProcess;
using testing::Visloc;

const std::string kRun = std::string(VISLOC_LOCALIZATION_DATA) + "/map_square";
constexpr int kFrames = 60;
constexpr double kRateHz = 10.0;  // 6 s of frames; the server then finishes in about a second.

int EnvInt(const char* name, int fallback) {
  const char* value = std::getenv(name);
  return value ? std::atoi(value) : fallback;
}

// What the server was doing when it was killed, from its log.
std::string Phase(const std::string& log) {
  if (log.find("event=map_built_over_link") != std::string::npos) return "published";
  if (log.find("event=mapping_finishing") != std::string::npos) return "finishing";
  return "frames";
}

class MappingKillE2eTest : public ::testing::Test {
 protected:
  void SetUp() override {
    // The map an unbroken run makes, built here (the server makes the same one: see
    // mapping_link_e2e_test), and the old map that every run replaces.
    ASSERT_EQ(Visloc({"map", "build", "--dataset", kRun, "--frames", Frames(), "--out",
                      work_.File("unbroken.db")})
                  .exit_code,
              0);
    ASSERT_EQ(Visloc({"map", "export", work_.File("unbroken.db"), "--keyframes",
                      work_.File("unbroken.tum")})
                  .exit_code,
              0);
    unbroken_ = testing::ReadTumLines(work_.File("unbroken.tum"));
    ASSERT_EQ(Visloc({"map", "build", "--dataset", kRun, "--frames", "0:8", "--out",
                      work_.File("old.db")})
                  .exit_code,
              0);
  }

  static std::string Frames() { return "0:" + std::to_string(kFrames); }

  // The largest distance of a keyframe of `map` from the unbroken run's, metres; +inf when their
  // keyframes differ in number or time.
  double KeyframeDistanceM(const std::string& map) const {
    const std::string tum = map + ".tum";
    if (Visloc({"map", "export", map, "--keyframes", tum}).exit_code != 0) return HUGE_VAL;
    const Trajectory keyframes = testing::ReadTumLines(tum);
    if (keyframes.size() != unbroken_.size()) return HUGE_VAL;
    double worst_m = 0.0;
    for (size_t k = 0; k < keyframes.size(); ++k) {
      if (keyframes[k].timestamp_ns != unbroken_[k].timestamp_ns) return HUGE_VAL;
      worst_m =
          std::max(worst_m, (keyframes[k].pose.translation - unbroken_[k].pose.translation).norm());
    }
    return worst_m;
  }

  // Whether the jobs' spool (MAPS/.mapping-jobs) holds no job within a few seconds: an ended
  // job removes its folder just after its last answer.
  bool SpoolEmptied() const {
    for (int attempt = 0; attempt < 100; ++attempt) {
      int jobs = 0;
      for (const auto& entry : std::filesystem::directory_iterator(maps_.File(".mapping-jobs"))) {
        jobs += entry.is_directory();
      }
      if (jobs == 0) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    return false;
  }

  TempDir maps_{"visloc_mapping_kill_maps"};
  TempDir work_{"visloc_mapping_kill_work"};
  Trajectory unbroken_;
};

TEST_F(MappingKillE2eTest, AServerKilledAtRandomMomentsEndsEveryRunWithTheUnbrokenMap) {
  const int runs = EnvInt("VISLOC_KILL_RUNS", 2);
  std::mt19937 random(static_cast<unsigned>(EnvInt("VISLOC_KILL_SEED", 58)));
  // Even runs are killed while frames arrive (from the job's start), odd ones after MappingEnd
  // (from the server's finishing: the adjustment, the learning, the publication, the answer).
  std::uniform_real_distribution<double> during_frames_s(0.2, kFrames / kRateHz - 0.5);
  std::uniform_real_distribution<double> after_end_s(0.0, 0.08);  // Finishing: ~80 ms.
  const std::string old_bytes = ReadFileBytes(work_.File("old.db"));
  int whole = 0;
  for (int run = 0; run < runs; ++run) {
    const std::string name = "hall";
    const std::string map_path = maps_.File(name + ".db");
    std::filesystem::copy_file(work_.File("old.db"), map_path,
                               std::filesystem::copy_options::overwrite_existing);
    auto server = std::make_unique<ServerProcess>(VISLOC_SERVER_PATH, maps_.path());
    const std::string address = server->address();
    const std::string out = work_.File("client.out"), err = work_.File("client.err");
    const int client =
        testing::SpawnProcess({VISLOC_CLI_PATH, "map", "build", "--server", address, "--name", name,
                               "--replace", "--dataset", kRun, "--frames", Frames(), "--rate",
                               std::to_string(kRateHz), "--resume-s", "60", "--json"},
                              out, err);
    ASSERT_TRUE(server->WaitForLog("event=mapping_started map=" + name));
    const bool after_end = run % 2 == 1;
    if (after_end) {
      ASSERT_TRUE(server->WaitForLog("event=mapping_finishing map=" + name, 30000));
    }
    const double kill_s = after_end ? after_end_s(random) : during_frames_s(random);
    std::this_thread::sleep_for(std::chrono::duration<double>(kill_s));
    server->Stop(SIGKILL);
    const std::string phase = Phase(server->Log());

    // Killed: the map of the name is the old one or the whole new one, never anything between.
    const std::string bytes = ReadFileBytes(map_path);
    const bool old_map_kept = bytes == old_bytes;
    if (!old_map_kept) {
      EXPECT_EQ(Visloc({"map", "info", map_path}).exit_code, 0) << "run " << run;
    }

    server = std::make_unique<ServerProcess>(VISLOC_SERVER_PATH, maps_.path(),
                                             std::vector<std::string>{"--listen", address});
    const int client_exit = testing::WaitProcess(client);
    const std::string answer = ReadFileBytes(out);
    const double distance_m = KeyframeDistanceM(map_path);
    const ProcessResult jobs = Visloc({"jobs", "--server", address, "--json"});
    const bool taken_up = jobs.out.find("its server stopped after") != std::string::npos;
    std::printf(
        "kill-run %d at %.2f s after %s during %s: client exit %d, old map %s, taken up %s, "
        "keyframes within %.3f mm of the unbroken run's\n",
        run, kill_s, after_end ? "MappingEnd" : "the start", phase.c_str(), client_exit,
        old_map_kept ? "kept" : "replaced", taken_up ? "yes" : "no", distance_m * 1e3);
    EXPECT_EQ(client_exit, 0) << "run " << run << ": " << ReadFileBytes(err);
    EXPECT_EQ(JsonNumber(answer, "frames"), kFrames) << answer;
    EXPECT_LT(distance_m, 1e-3) << "run " << run;
    // A server killed after its answer had gone has nothing left to take up.
    if (phase != "published") {
      EXPECT_TRUE(taken_up) << jobs.out;
      EXPECT_THAT(jobs.out, HasSubstr("\"state\":\"published\"")) << jobs.out;
    }
    EXPECT_TRUE(SpoolEmptied()) << "run " << run << ": " << server->Log();
    server.reset();  // Before the next run's server starts on the same folder.
    whole += client_exit == 0 && distance_m < 1e-3;
  }
  std::printf("kill-runs %d of %d whole\n", whole, runs);
}

// A spool a restart cannot use (here a job's start that is not one) is listed as failed with
// the reason and dropped; the next job's id follows it. A second server on the same folder
// leaves the spool to the first: its jobs are refused by name.
TEST_F(MappingKillE2eTest, AnUnusableSpoolIsNamedAndASecondServerLeavesTheSpoolAlone) {
  const std::string job = maps_.File(".mapping-jobs/5");
  std::filesystem::create_directories(job);
  std::ofstream(job + "/start.pb") << "not a protobuf at all";
  ServerProcess server(VISLOC_SERVER_PATH, maps_.path());
  ASSERT_TRUE(server.WaitForLog("event=mapping_spool_unusable job=5"));
  const ProcessResult jobs = Visloc({"jobs", "--server", server.address(), "--json"});
  EXPECT_THAT(jobs.out, HasSubstr("\"job\":5,"));
  EXPECT_THAT(jobs.out, HasSubstr("\"state\":\"failed\""));
  EXPECT_THAT(jobs.out, HasSubstr("is not a mapping job's start"));
  EXPECT_THAT(jobs.out, HasSubstr("found its spool unusable"));
  EXPECT_FALSE(std::filesystem::exists(job));

  const ProcessResult built = Visloc({"map", "build", "--server", server.address(), "--name",
                                      "hall", "--dataset", kRun, "--frames", "0:8", "--json"});
  ASSERT_EQ(built.exit_code, 0) << built.err;
  EXPECT_GE(JsonNumber(built.out, "job"), 6) << built.out;

  ServerProcess second(VISLOC_SERVER_PATH, maps_.path());
  const ProcessResult refused = Visloc({"map", "build", "--server", second.address(), "--name",
                                        "yard", "--dataset", kRun, "--frames", "0:8"});
  EXPECT_EQ(refused.exit_code, 1);
  EXPECT_THAT(refused.err, HasSubstr("is held by another visloc-server on the same folder"));
}

}  // namespace
}  // namespace visloc
