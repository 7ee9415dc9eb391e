// The live sessions end to end: real `visloc stream` robots on a real visloc-server, read back
// through the Fleet service by `visloc sessions` and by a watching client. The server's one
// registry must show each robot as it streams (map, name, frames, frame rate, status, pose), the
// kidnapped robot without a pose while its camera is covered and with one again after, and
// nothing once the robots are done. Tokens guard the list as they guard localization.

#include <gmock/gmock.h>
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>

#include "core/util/temp_dir.h"
#include "core/util/text_file.h"
#include "tests/support/e2e.h"
#include "tests/support/process.h"
#include "visloc/v1/visloc.grpc.pb.h"

namespace visloc {
namespace {

using ::testing::AllOf;
using ::testing::HasSubstr;
using testing::ProcessResult;
using testing::ServerProcess;
using testing::Visloc;

const std::string kData = VISLOC_LOCALIZATION_DATA;

std::vector<std::string> Robot(const std::string& address, const std::string& robot_id,
                               const std::string& sequence) {
  return {VISLOC_CLI_PATH, "stream",     "--server", address,     "--map",
          "square",        "--robot-id", robot_id,   "--dataset", kData + "/" + sequence,
          "--rate",        "15",         "--json"};
}

const v1::SessionSummary* Find(const v1::ListSessionsResponse& fleet, const std::string& robot) {
  for (const v1::SessionSummary& s : fleet.sessions()) {
    if (s.robot_id() == robot) return &s;
  }
  return nullptr;
}

class FleetE2eTest : public ::testing::Test {
 protected:
  void SetUp() override { std::filesystem::copy_file(kData + "/map.db", maps_.File("square.db")); }
  TempDir maps_{"visloc_fleet_maps"};
};

TEST_F(FleetE2eTest, TheListShowsEachRobotAsItStreamsAndTheKidnappedOneLostAndBack) {
  ServerProcess server(VISLOC_SERVER_PATH, maps_.path());
  const int kidnapped = testing::SpawnProcess(Robot(server.address(), "rover-kidnap", "kidnap"));
  const int walker = testing::SpawnProcess(Robot(server.address(), "rover-walk", "query_square"));

  // A client watching every 100 ms while the robots stream: the kidnapped robot must be seen
  // without a pose (its camera covered) and with one again.
  auto stub =
      v1::Fleet::NewStub(grpc::CreateChannel(server.address(), grpc::InsecureChannelCredentials()));
  grpc::ClientContext watch;
  v1::WatchSessionsRequest request;
  request.set_interval_ms(100);
  auto reader = stub->WatchSessions(&watch, request);
  bool both_seen = false, lost_seen = false, back_seen = false;
  double walker_rate_hz = 0;
  v1::ListSessionsResponse fleet;
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (!back_seen && std::chrono::steady_clock::now() < give_up && reader->Read(&fleet)) {
    const v1::SessionSummary* k = Find(fleet, "rover-kidnap");
    const v1::SessionSummary* w = Find(fleet, "rover-walk");
    if (!both_seen && k && w && k->frames() > 20 && w->frames() > 20) {
      both_seen = true;
      EXPECT_EQ(k->map_name(), "square");
      walker_rate_hz = w->frame_rate_hz();
      // The CLI reads the same registry, while both robots still stream.
      const ProcessResult listed = Visloc({"sessions", "--server", server.address(), "--json"});
      ASSERT_EQ(listed.exit_code, 0) << listed.err;
      EXPECT_THAT(listed.out, HasSubstr("\"robot\":\"rover-walk\""));
      EXPECT_THAT(listed.out, HasSubstr("\"robot\":\"rover-kidnap\""));
      const ProcessResult table = Visloc({"sessions", "--server", server.address()});
      EXPECT_THAT(table.out, HasSubstr("rover-walk"));
      EXPECT_THAT(table.out, HasSubstr("square"));
    }
    if (k && k->localized() > 10 && !k->has_pose() && k->status() == v1::STATUS_LOST) {
      lost_seen = true;
      EXPECT_GT(k->without_pose_since_unix_ns(), 0);
    }
    if (lost_seen && k && k->has_pose()) {
      back_seen = true;
      EXPECT_EQ(k->without_pose_since_unix_ns(), 0);
      // The first answer back may be a limited fix (the frames a loaded robot delivered after
      // the kidnapping may leave one that sees part of the map) or follow a skipped frame: each
      // status is held to its own floor (LocalizerOptions: limited 12 inliers; tracked or
      // relocalized 30, at a ratio the policy sets at 0.4 and this test, as before, at 0.3).
      // Any other status with a pose is the motion's, not a visual fix: no floor.
      const std::string status = v1::Status_Name(k->status());
      if (k->status() == v1::STATUS_LIMITED) {
        EXPECT_GE(k->inliers(), 12u) << status;
      } else if (k->status() == v1::STATUS_TRACKING || k->status() == v1::STATUS_RELOCALIZED) {
        EXPECT_GE(k->inliers(), 30u) << status;
        EXPECT_GT(k->inlier_ratio(), 0.3) << status;
      }
    }
  }
  watch.TryCancel();
  reader->Finish();
  EXPECT_TRUE(both_seen);
  EXPECT_TRUE(lost_seen) << "the kidnapped robot never showed lost";
  EXPECT_TRUE(back_seen) << "the kidnapped robot never showed a pose again";
  // Paced at 15 Hz; a sanitizer build answers slower and the robots drop frames on their side.
  EXPECT_GT(walker_rate_hz, 4.0);
  EXPECT_LT(walker_rate_hz, 25.0);

  const ProcessResult watched = Visloc({"sessions", "--server", server.address(), "--watch",
                                        "--count", "3", "--interval-ms", "100", "--json"});
  ASSERT_EQ(watched.exit_code, 0) << watched.err;
  EXPECT_EQ(testing::CountOccurrences(watched.out, "\"max_sessions\":64"), 3u) << watched.out;

  EXPECT_EQ(testing::WaitProcess(kidnapped), 0);
  EXPECT_EQ(testing::WaitProcess(walker), 0);
  ASSERT_TRUE(testing::WaitUntil([&] {
    return Visloc({"sessions", "--server", server.address(), "--json"}).out.find("\"robot\"") ==
           std::string::npos;
  }));
}

// `visloc load`: many robots from one process, each frame accounted for (answered, skipped by the
// server, dropped by the link's policy, late or undelivered), and a map the server does not
// have named in the error; at 5 Hz, a rate a sanitizer build keeps up with on a loaded machine
// (at 10 Hz a CI run answered fewer than 90%). Its speed is a benchmark's to measure
// (scripts/capacity.sh).
TEST_F(FleetE2eTest, ALoadOfRobotsFromOneProcessIsAnsweredFrameByFrame) {
  ServerProcess server(VISLOC_SERVER_PATH, maps_.path());
  const std::vector<std::string> load = {"load",
                                         "--server",
                                         server.address(),
                                         "--map",
                                         "square",
                                         "--dataset",
                                         kData + "/query_square",
                                         "--robots",
                                         "4",
                                         "--rate",
                                         "5",
                                         "--duration-s",
                                         "4",
                                         "--json"};
  const ProcessResult run = Visloc(load);
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const double frames = testing::JsonNumber(run.out, "frames");
  const double answered = testing::JsonNumber(run.out, "answered");
  EXPECT_GE(frames, 4 * 5 * 4 - 4);
  EXPECT_LE(frames, 4 * 5 * 4 + 4);
  double accounted = answered;
  for (const char* fate : {"skipped", "late", "dropped", "undelivered"}) {
    accounted += testing::JsonNumber(run.out, fate);
  }
  EXPECT_EQ(accounted, frames) << run.out;
  EXPECT_GE(answered, 0.9 * frames) << run.out;
  EXPECT_GE(testing::JsonNumber(run.out, "localized"), 0.9 * answered) << run.out;

  std::vector<std::string> unknown = load;
  unknown[4] = "nowhere";
  const ProcessResult refused = Visloc(unknown);
  EXPECT_EQ(refused.exit_code, 1);
  EXPECT_THAT(refused.err, HasSubstr("nowhere"));

  std::vector<std::string> no_robots = load;
  no_robots[8] = "0";
  const ProcessResult usage = Visloc(no_robots);
  EXPECT_EQ(usage.exit_code, 2);
  EXPECT_THAT(usage.err, HasSubstr("--robots is 1..256"));
}

// A session on the raw wire for `map` that sends no frame: how it ends (OK when admitted).
grpc::Status SessionStartOf(const std::string& address, const std::string& map) {
  auto stub =
      v1::Localization::NewStub(grpc::CreateChannel(address, grpc::InsecureChannelCredentials()));
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(2));
  auto call = stub->Localize(&context);
  v1::LocalizeRequest start;
  start.mutable_start()->set_map_name(map);
  call->Write(start);
  call->WritesDone();
  return call->Finish();
}

// A newcomer on the raw wire, tried every 300 ms for 7 s until the server refuses it for
// capacity (once the robots streaming on it fill its window); its last answer.
grpc::Status RefusalOf(const std::string& address) {
  grpc::Status refused;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(7);
  while (std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    refused = SessionStartOf(address, "square");
    if (refused.error_code() == grpc::StatusCode::RESOURCE_EXHAUSTED) break;
  }
  return refused;
}

// `visloc load` of ROBOTS robots for SECONDS on the square map at SERVER, at 5 Hz: a rate a
// sanitizer's engine (ten times slower) keeps up with on one worker.
std::vector<std::string> LoadOf(const std::string& server, int robots, int seconds) {
  return {VISLOC_CLI_PATH, "load",
          "--server",      server,
          "--map",         "square",
          "--dataset",     kData + "/query_square",
          "--robots",      std::to_string(robots),
          "--rate",        "5",
          "--duration-s",  std::to_string(seconds),
          "--json"};
}

// Admission control (server/admission.h): robots streaming on a server whose one worker their
// frames keep busy; newcomers are refused with RESOURCE_EXHAUSTED and the reason, the client
// library backs off instead of knocking at once, and the robots already on it keep every frame.
TEST_F(FleetE2eTest, NewRobotsOnAServerAtCapacityAreRefusedByNameAndTheOthersKeepTheirPace) {
  // A limit low enough that three robots of the fixture reach it on any machine.
  ServerProcess server(VISLOC_SERVER_PATH, maps_.path(),
                       {"--threads", "1", "--admit-busy", "0.01", "--admit-wait-ms", "1000"});
  TempDir out("visloc_admission_out");
  const auto load = [&](int robots, int seconds) {
    return LoadOf(server.address(), robots, seconds);
  };
  const int first =
      testing::SpawnProcess(load(3, 12), out.File("first.json"), out.File("first.err"));
  const grpc::Status refused = RefusalOf(server.address());
  ASSERT_EQ(refused.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << refused.error_message();
  EXPECT_THAT(refused.error_message(),
              AllOf(HasSubstr("server at capacity: its workers (1) were"), HasSubstr("sessions"),
                    HasSubstr("over the 1% that keeps its robots on time"),
                    HasSubstr("Retry in a few seconds, or on another replica")));
  // A robot asking for a map the server does not have hears that, the lasting reason, and not
  // "retry later": no retry would find the map.
  const grpc::Status unknown = SessionStartOf(server.address(), "nope");
  EXPECT_EQ(unknown.error_code(), grpc::StatusCode::NOT_FOUND) << unknown.error_message();
  EXPECT_THAT(unknown.error_message(), HasSubstr("no map named 'nope'"));
  // Two robots arriving through the client library: refused, and counted so.
  const ProcessResult newcomers = testing::RunProcess(load(2, 2));
  ASSERT_EQ(newcomers.exit_code, 0) << newcomers.err;
  EXPECT_EQ(testing::JsonNumber(newcomers.out, "refused_robots"), 2) << newcomers.out;
  EXPECT_EQ(testing::WaitProcess(first), 0);
  const std::string first_out = ReadFileBytes(out.File("first.json"));
  EXPECT_EQ(testing::JsonNumber(first_out, "refused_robots"), 0) << first_out;
  EXPECT_GE(testing::JsonNumber(first_out, "answered"),
            0.95 * testing::JsonNumber(first_out, "frames"))
      << first_out;
  // Each refusal logged with its reason; the newcomers' retries spaced by the library's backoff
  // (a second, doubling), not at the link's pace: a handful in their 2 s, not dozens.
  const std::string log = server.Log();
  int refusals = 0;
  for (size_t at = log.find("server at capacity"); at != std::string::npos;
       at = log.find("server at capacity", at + 1)) {
    ++refusals;
  }
  EXPECT_GE(refusals, 3);
  EXPECT_LE(refusals, 12) << "the library retried a refused session without backing off";
}

// Two replicas, one at capacity: robots given both (a replica list, each robot's shuffled) are
// all served, those that asked the full one first by the other after its refusal.
TEST_F(FleetE2eTest, ARobotRefusedByAReplicaAtCapacityIsServedByTheOther) {
  ServerProcess full(VISLOC_SERVER_PATH, maps_.path(),
                     {"--threads", "1", "--admit-busy", "0.01", "--admit-wait-ms", "1000"});
  // The replica with room: its own admission off, so that on a slow machine (a CI run under
  // ASan) its load of six newcomers is not itself refused; this test is about the turn from
  // the full replica to the other, not the other's limit.
  ServerProcess other(VISLOC_SERVER_PATH, maps_.path(), {"--admit-busy", "0"});
  TempDir out("visloc_replicas_out");
  const int on_full = testing::SpawnProcess(LoadOf(full.address(), 3, 12), out.File("full.json"),
                                            out.File("full.err"));
  ASSERT_EQ(RefusalOf(full.address()).error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  const ProcessResult newcomers =
      testing::RunProcess(LoadOf("ipv4:" + full.address() + "," + other.address(), 6, 3));
  ASSERT_EQ(newcomers.exit_code, 0) << newcomers.err;
  EXPECT_EQ(testing::JsonNumber(newcomers.out, "refused_robots"), 0) << newcomers.out;
  // Served. Six robots at 5 Hz are more than a CI machine's ASan build answers in full (a run
  // answered 78 of 87 frames and skipped 7 stale ones, as NEWEST_ONLY asks): how many the
  // replica with room answers is its capacity, not the turn this test is about, so the bound
  // only says the robots were served.
  EXPECT_GE(testing::JsonNumber(newcomers.out, "answered"),
            0.5 * testing::JsonNumber(newcomers.out, "frames"))
      << newcomers.out;
  // Frames sent to the full replica before its refusal came back were never admitted: they
  // are awaiting admission, not frames the link lost (a CI run counted 9 of them as lost).
  EXPECT_EQ(testing::JsonNumber(newcomers.out, "undelivered"), 0) << newcomers.out;
  const std::string other_log = other.Log();
  int started = 0;
  for (size_t at = other_log.find("event=session_start"); at != std::string::npos;
       at = other_log.find("event=session_start", at + 1)) {
    ++started;
  }
  EXPECT_EQ(started, 6) << "every newcomer ends on the replica with room";
  EXPECT_EQ(testing::WaitProcess(on_full), 0);
}

TEST_F(FleetE2eTest, TheListNeedsAToken) {
  TempDir files("visloc_fleet_files");
  std::ofstream(files.File("tokens")) << "robot-token-0123456789 localize\n";
  ServerProcess server(VISLOC_SERVER_PATH, maps_.path(), {"--tokens", files.File("tokens")});
  const ProcessResult anonymous = Visloc({"sessions", "--server", server.address()});
  EXPECT_EQ(anonymous.exit_code, 1);
  EXPECT_THAT(anonymous.err, HasSubstr("--token"));
  const ProcessResult robot = Visloc(
      {"sessions", "--server", server.address(), "--token", "robot-token-0123456789", "--json"});
  EXPECT_EQ(robot.exit_code, 0) << robot.err;
  EXPECT_THAT(robot.out, HasSubstr("\"sessions\":[]"));
}

}  // namespace
}  // namespace visloc
