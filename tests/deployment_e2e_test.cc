// The scale-out deployment (docs/deployment.md), with real binaries on loopback: replicas of
// visloc-server on one shared maps folder, one of them the admin server that writes it and the
// others read-only; robots spread over the replicas by the client (each session on one replica,
// a dead replica skipped); `visloc health` as the container health check.

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <regex>

#include "core/util/temp_dir.h"
#include "core/util/text_file.h"
#include "tests/support/e2e.h"
#include "tests/support/process.h"

namespace visloc {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using testing::JsonNumber;
using testing::ProcessResult;
using testing::ServerProcess;
using testing::Visloc;

const std::string kData = VISLOC_LOCALIZATION_DATA;

// A replay (--rate 0): every frame is sent and answered, however loaded the machine, so a
// session's frame count says whether it stayed on one replica (a real-time stream may drop frames
// its link cannot keep up with: a CI run under ASan saw 8 of 10).
ProcessResult Stream(const std::string& server, const std::string& map, int frames) {
  return Visloc({"stream", "--server", server, "--map", map, "--dataset", kData + "/query_square",
                 "--frames", std::to_string(frames), "--rate", "0", "--json"});
}

// The frame counts of the sessions a server's log says ended.
std::vector<int> SessionFrames(const ServerProcess& server) {
  const std::string log = server.Log();
  static const std::regex kEnd("event=session_end session=\\d+ map=\\S+ frames=(\\d+)");
  std::vector<int> frames;
  for (std::sregex_iterator it(log.begin(), log.end(), kEnd), end; it != end; ++it) {
    frames.push_back(std::stoi((*it)[1]));
  }
  return frames;
}

class DeploymentE2eTest : public ::testing::Test {
 protected:
  void SetUp() override { fs::copy_file(kData + "/map.db", shared_.File("square.db")); }
  TempDir shared_{"visloc_deploy_maps"};  // The volume every replica mounts.
  TempDir local_{"visloc_deploy_local"};
};

TEST_F(DeploymentE2eTest, HealthCheckSaysServingAndFailsWhenTheServerIsGone) {
  ServerProcess server(VISLOC_SERVER_PATH, shared_.path());
  const ProcessResult serving = Visloc({"health", "--server", server.address()});
  EXPECT_EQ(serving.exit_code, 0) << serving.err;
  EXPECT_EQ(serving.out, server.address() + ": SERVING\n");
  const ProcessResult one = Visloc(
      {"health", "--server", server.address(), "--service", "visloc.v1.Localization", "--json"});
  EXPECT_EQ(one.exit_code, 0) << one.err;
  EXPECT_THAT(one.out, HasSubstr("\"status\":\"SERVING\""));
  const ProcessResult unknown =
      Visloc({"health", "--server", server.address(), "--service", "no.such.Service"});
  EXPECT_EQ(unknown.exit_code, 1);
  EXPECT_THAT(unknown.err, HasSubstr("service name unknown (gRPC code 5)"));

  ASSERT_EQ(server.Stop(), 0);
  const ProcessResult gone = Visloc({"health", "--server", server.address(), "--timeout-s", "2"});
  EXPECT_EQ(gone.exit_code, 1);
  EXPECT_THAT(gone.err, HasSubstr("server " + server.address()));
}

TEST_F(DeploymentE2eTest, ReadOnlyReplicaServesTheSharedFolderAndRefusesChanges) {
  // Another server's upload in progress, by a process id this replica cannot see.
  const std::string in_progress = shared_.File(".incoming.db.tmp-999999-1");
  std::ofstream(in_progress) << "half an upload";
  ServerProcess admin_server(VISLOC_SERVER_PATH, shared_.path());  // Writes the folder...
  // ...after which a replica starts on it: it must not touch the staging file.
  std::ofstream(in_progress) << "half an upload";
  ServerProcess replica(VISLOC_SERVER_PATH, shared_.path(), {"--maps-read-only"});
  EXPECT_TRUE(fs::exists(in_progress));
  EXPECT_THAT(replica.Log(), HasSubstr("maps_read_only=yes"));

  testing::SaveLabMap(local_.File("lab.db"));
  const ProcessResult refused =
      Visloc({"map", "upload", local_.File("lab.db"), "--server", replica.address()});
  EXPECT_EQ(refused.exit_code, 1);
  EXPECT_THAT(refused.err, HasSubstr("read-only (--maps-read-only)"));
  EXPECT_THAT(refused.err, HasSubstr("gRPC code 9"));  // FAILED_PRECONDITION
  EXPECT_EQ(Visloc({"map", "delete", "square", "--server", replica.address()}).exit_code, 1);
  EXPECT_EQ(Visloc({"map", "rename", "square", "moved", "--server", replica.address()}).exit_code,
            1);
  EXPECT_TRUE(fs::exists(shared_.File("square.db")));
  EXPECT_FALSE(fs::exists(shared_.File("lab.db")));
  EXPECT_FALSE(fs::exists(shared_.File("moved.db")));

  // Uploads go through the admin server; the replica serves the new map at once.
  const ProcessResult uploaded =
      Visloc({"map", "upload", local_.File("lab.db"), "--server", admin_server.address()});
  ASSERT_EQ(uploaded.exit_code, 0) << uploaded.err;
  const ProcessResult list = Visloc({"map", "list", "--server", replica.address(), "--json"});
  EXPECT_THAT(list.out, HasSubstr("\"name\":\"lab\""));
  const ProcessResult downloaded = Visloc(
      {"map", "download", "lab", "--out", local_.File("copy.db"), "--server", replica.address()});
  EXPECT_EQ(downloaded.exit_code, 0) << downloaded.err;
  const ProcessResult robot = Stream(replica.address(), "square", 20);
  ASSERT_EQ(robot.exit_code, 0) << robot.err;
  EXPECT_EQ(JsonNumber(robot.out, "localized_fraction"), 1.0);
}

TEST_F(DeploymentE2eTest, RobotsSpreadOverReplicasAndSkipADeadOne) {
  ServerProcess a(VISLOC_SERVER_PATH, shared_.path());
  ServerProcess b(VISLOC_SERVER_PATH, shared_.path(), {"--maps-read-only"});
  const std::string fleet = "ipv4:" + a.address() + "," + b.address();
  // Twelve robot processes, one session each. Each process starts on a random replica, so
  // all twelve on one replica has probability 2^-11.
  constexpr int kRobots = 12, kFrames = 10;
  for (int robot = 0; robot < kRobots; ++robot) {
    const ProcessResult result = Stream(fleet, "square", kFrames);
    ASSERT_EQ(result.exit_code, 0) << result.err;
    EXPECT_EQ(JsonNumber(result.out, "localized_fraction"), 1.0);
  }
  const std::vector<int> on_a = SessionFrames(a), on_b = SessionFrames(b);
  EXPECT_EQ(on_a.size() + on_b.size(), static_cast<size_t>(kRobots));
  EXPECT_GE(on_a.size(), 1u);
  EXPECT_GE(on_b.size(), 1u);
  // A session never moves: each replica saw whole sessions.
  for (const int frames : on_a) EXPECT_EQ(frames, kFrames);
  for (const int frames : on_b) EXPECT_EQ(frames, kFrames);

  // A replica dies (SIGKILL: no drain); new robots find the other one.
  a.Stop(SIGKILL);
  for (int robot = 0; robot < 3; ++robot) {
    const ProcessResult result = Stream(fleet, "square", kFrames);
    ASSERT_EQ(result.exit_code, 0) << result.err;
    EXPECT_EQ(JsonNumber(result.out, "localized_fraction"), 1.0);
  }
  EXPECT_EQ(SessionFrames(b).size(), on_b.size() + 3);
}

}  // namespace
}  // namespace visloc
