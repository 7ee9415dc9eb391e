// End-to-end through the real server: visloc-server on a loopback port with a maps folder, the
// real `visloc stream` client over gRPC, on the localization fixture's map and sequences.

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <thread>

#include <grpcpp/grpcpp.h>

#include "core/util/strings.h"
#include "core/util/temp_dir.h"
#include "core/util/text_file.h"
#include "dataset/dataset.h"
#include "dataset/tum.h"
#include "grpc/health/v1/health.grpc.pb.h"
#include "proto/convert.h"
#include "tests/support/e2e.h"
#include "tests/support/process.h"
#include "visloc/v1/visloc.grpc.pb.h"

namespace visloc {
namespace {

using ::testing::HasSubstr;
using testing::JsonNumber;
using testing::ProcessResult;
using testing::ServerProcess;
using testing::Visloc;

const std::string kData = VISLOC_LOCALIZATION_DATA;

// A maps folder holding the fixture's map as "square".
class ServerE2eTest : public ::testing::Test {
 protected:
  void SetUp() override { std::filesystem::copy_file(kData + "/map.db", maps_.File("square.db")); }
  TempDir maps_{"visloc_server_maps"};
  TempDir out_{"visloc_server_out"};
};

TEST_F(ServerE2eTest, StreamsAKidnappingThroughTheServerLikeTheInProcessEngine) {
  ServerProcess server(VISLOC_SERVER_PATH, maps_.path());
  const std::string stats = out_.File("stats.csv");
  const ProcessResult stream =
      Visloc({"stream", "--server", server.address(), "--map", "square", "--dataset",
              kData + "/kidnap", "--rate", "0", "--stats", stats, "--trajectory",
              out_.File("est.tum"), "--gt", kData + "/kidnap/groundtruth_map.tum", "--json"});
  ASSERT_EQ(stream.exit_code, 0) << stream.err;
  EXPECT_EQ(JsonNumber(stream.out, "errors"), 0);
  EXPECT_EQ(JsonNumber(stream.out, "frames"), 150);
  EXPECT_NEAR(JsonNumber(stream.out, "localized_fraction"), 132.0 / 150, 0.01);
  EXPECT_LT(JsonNumber(stream.out, "position_max_m"), 0.05);
  // The same answers as the engine in-process on the same frames.
  const ProcessResult local = Visloc({"localize", "--map", kData + "/map.db", "--dataset",
                                      kData + "/kidnap", "--stats", out_.File("local.csv")});
  ASSERT_EQ(local.exit_code, 0) << local.err;
  const auto remote_rows = ReadTextLines(stats), local_rows = ReadTextLines(out_.File("local.csv"));
  ASSERT_EQ(remote_rows.size(), local_rows.size());
  for (size_t i = 1; i < remote_rows.size(); ++i) {
    // timestamp, status and source agree exactly.
    const auto head = [](const std::string& row) {
      return row.substr(0, row.find(',', row.find(',', row.find(',') + 1) + 1));
    };
    EXPECT_EQ(head(remote_rows[i].text), head(local_rows[i].text)) << "row " << i;
  }
  // What relocalization did travels the wire too: the search's kind and its feature passes, none
  // and 0 on frames without a search, 1 or 2 on the frames after the kidnapping that searched.
  const std::vector<std::string> header = Split(remote_rows[0].text, ',');
  const auto column = [&](const char* name) {
    return static_cast<size_t>(std::find(header.begin(), header.end(), name) - header.begin());
  };
  const size_t kind = column("relocalization"), passes = column("relocalization_feature_passes");
  ASSERT_LT(kind, header.size());
  ASSERT_LT(passes, header.size());
  int searched = 0;
  for (size_t i = 1; i < remote_rows.size(); ++i) {
    const std::vector<std::string> remote = Split(remote_rows[i].text, ',');
    const std::vector<std::string> local = Split(local_rows[i].text, ',');
    ASSERT_EQ(remote.size(), header.size()) << "row " << i;
    EXPECT_EQ(remote[kind], local[kind]) << "row " << i;
    EXPECT_EQ(remote[passes], local[passes]) << "row " << i;
    if (remote[kind] == "none") {
      EXPECT_EQ(remote[passes], "0") << "row " << i;
    } else {
      EXPECT_THAT(remote[passes], ::testing::AnyOf("1", "2")) << "row " << i;
      ++searched;
    }
  }
  EXPECT_GT(searched, 0);
  EXPECT_EQ(server.Stop(), 0);
  const std::string log = server.Log();
  EXPECT_THAT(log, HasSubstr("event=session_start session=1 map=square"));
  EXPECT_THAT(
      log, HasSubstr("event=session_end session=1 map=square frames=150 localized_fraction=0.880"));
  // A one-camera session has no helper threads: its end line names none (as before rigs).
  EXPECT_THAT(log, ::testing::Not(HasSubstr("helper_wakes")));
  EXPECT_THAT(log, HasSubstr("event=server_stop"));
}

TEST_F(ServerE2eTest, UnknownMapsAndEscapingNamesAreRefusedAndTheServerGoesOn) {
  ServerProcess server(VISLOC_SERVER_PATH, maps_.path());
  const ProcessResult unknown = Visloc({"stream", "--server", server.address(), "--map", "nope",
                                        "--dataset", kData + "/query_square", "--frames", "3"});
  EXPECT_EQ(unknown.exit_code, 1);
  EXPECT_THAT(unknown.err, HasSubstr("no map named 'nope'"));
  EXPECT_THAT(unknown.err, HasSubstr("gRPC code 5"));  // NOT_FOUND
  const ProcessResult escaping =
      Visloc({"stream", "--server", server.address(), "--map", "../square", "--dataset",
              kData + "/query_square", "--frames", "3"});
  EXPECT_EQ(escaping.exit_code, 1);
  EXPECT_THAT(escaping.err, HasSubstr("invalid map name '../square'"));
  const ProcessResult good =
      Visloc({"stream", "--server", server.address(), "--map", "square", "--dataset",
              kData + "/query_square", "--frames", "20", "--rate", "0", "--json"});
  ASSERT_EQ(good.exit_code, 0) << good.err;
  EXPECT_EQ(JsonNumber(good.out, "localized_fraction"), 1.0);
}

// Eight frames in flight keep several queued at the server, so that the newest-only policy
// always has frames to skip (47-50 of 60). With the default two a frame is skipped only when
// the next arrives before the engine picks up the one queued, a race: 0-9 of 60, and no skip at
// all in about one run of ten.
TEST_F(ServerE2eTest, NewestOnlyPolicyAnswersSkippedFramesToo) {
  ServerProcess server(VISLOC_SERVER_PATH, maps_.path());
  const ProcessResult stream =
      Visloc({"stream", "--server", server.address(), "--map", "square", "--dataset",
              kData + "/query_square", "--frames", "60", "--rate", "0", "--policy", "newest",
              "--max-in-flight", "8", "--stats", out_.File("s.csv"), "--json"});
  ASSERT_EQ(stream.exit_code, 0) << stream.err;
  const double skipped = JsonNumber(stream.out, "skipped");
  const double answered = JsonNumber(stream.out, "frames");
  EXPECT_EQ(skipped + answered, 60) << stream.out;  // One response per frame.
  EXPECT_GT(skipped, 0) << stream.out;
  EXPECT_GE(answered, 1) << stream.out;
}

TEST_F(ServerE2eTest, FramesOverTheSessionRateLimitAreSkippedWithAReason) {
  ServerProcess server(VISLOC_SERVER_PATH, maps_.path(), {"--max-frame-rate-hz", "5"});
  // 40 frames as fast as the client can send: one second of burst (5 frames) plus what 5 Hz
  // refills while they are processed gets through; the rest is answered SKIPPED.
  const ProcessResult flood =
      Visloc({"stream", "--server", server.address(), "--map", "square", "--dataset",
              kData + "/query_square", "--frames", "40", "--rate", "0", "--json"});
  ASSERT_EQ(flood.exit_code, 0) << flood.err;
  const double skipped = JsonNumber(flood.out, "skipped");
  EXPECT_EQ(skipped + JsonNumber(flood.out, "frames"), 40);  // Still one answer per frame.
  EXPECT_GE(skipped, 25);
  EXPECT_THAT(flood.err, HasSubstr("over the session frame-rate limit of 5.0 Hz"));
  EXPECT_THAT(server.Log(), HasSubstr("max_frame_rate_hz=5.0"));
  // The server's own time is its answered frames' (0.8 ms or more each), not the skipped ones'
  // (microseconds), which are most of the answers here.
  EXPECT_GT(JsonNumber(flood.out, "server_ms_p50"), 0.3) << flood.out;
  // A client within the limit loses nothing.
  const ProcessResult steady =
      Visloc({"stream", "--server", server.address(), "--map", "square", "--dataset",
              kData + "/query_square", "--frames", "10", "--rate", "4", "--json"});
  ASSERT_EQ(steady.exit_code, 0) << steady.err;
  EXPECT_EQ(JsonNumber(steady.out, "skipped"), 0);
}

TEST_F(ServerE2eTest, RelocalizesOneImageAndRefusesAnOutOfMapImage) {
  ServerProcess server(VISLOC_SERVER_PATH, maps_.path());
  // Frame 60 of the offset square, compared with its ground truth.
  const Dataset dataset = ReadDataset(kData + "/query_square");
  const ProcessResult found =
      Visloc({"relocalize", "--server", server.address(), "--map", "square", "--dataset",
              kData + "/query_square", dataset.frames[60].left_path, "--json"});
  ASSERT_EQ(found.exit_code, 0) << found.err << found.out;
  const Trajectory gt = ReadTum(kData + "/query_square/groundtruth_map.tum");
  const auto truth = InterpolateAt(gt, dataset.frames[60].timestamp_ns, 1'000'000);
  ASSERT_TRUE(truth.has_value());
  const Eigen::Vector3d position(JsonNumber(found.out, "tx"), JsonNumber(found.out, "ty"),
                                 JsonNumber(found.out, "tz"));
  EXPECT_LT((position - truth->translation).norm(), 0.05);
  EXPECT_GT(JsonNumber(found.out, "inliers"), 40);
  // A robot with no dataset names its camera by the sensor.yaml its calibration wrote.
  const ProcessResult by_yaml = Visloc(
      {"relocalize", "--server", server.address(), "--map", "square", "--camera-yaml",
       kData + "/query_square/mav0/cam0/sensor.yaml", dataset.frames[60].left_path, "--json"});
  ASSERT_EQ(by_yaml.exit_code, 0) << by_yaml.err << by_yaml.out;
  EXPECT_EQ(JsonNumber(by_yaml.out, "tx"), JsonNumber(found.out, "tx"));
  EXPECT_EQ(JsonNumber(by_yaml.out, "inliers"), JsonNumber(found.out, "inliers"));
  const ProcessResult both =
      Visloc({"relocalize", "--server", server.address(), "--map", "square", "--dataset",
              kData + "/query_square", "--camera-yaml",
              kData + "/query_square/mav0/cam0/sensor.yaml", dataset.frames[60].left_path});
  EXPECT_EQ(both.exit_code, 2);
  EXPECT_THAT(both.err, HasSubstr("--dataset or --camera-yaml, not both"));

  const Dataset elsewhere = ReadDataset(kData + "/outofmap");
  // Without --dataset the map's camera is assumed (the same rig here).
  const ProcessResult refused = Visloc({"relocalize", "--server", server.address(), "--map",
                                        "square", elsewhere.frames[10].left_path});
  EXPECT_EQ(refused.exit_code, 3);
  EXPECT_THAT(refused.out, HasSubstr("not localized"));
}

// The Relocalize RPC and a session's first frame run the same query pipeline (detector
// settings, radii scaled to the camera): on the same 640x480 image they give the same fix. The
// map was made at 320x240, so relocalization resamples the image to the map's focal length;
// described at the camera's own pixels, its corners matched half as many points (186 inliers)
// and the bag of words hardly told the keyframes apart.
TEST_F(ServerE2eTest, TheRpcAndASessionGiveTheSameFirstFixAt640x480) {
  const std::string rendered = out_.File("q640");
  const ProcessResult sim =
      Visloc({"sim", "--out", rendered, "--sequence", "query_square", "--resolution", "640x480",
              "--frames", "1", "--no-contact-sheet"});
  ASSERT_EQ(sim.exit_code, 0) << sim.err;
  const std::string dataset_dir = rendered + "/query_square";
  const Dataset dataset = ReadDataset(dataset_dir);
  ServerProcess server(VISLOC_SERVER_PATH, maps_.path());
  const ProcessResult rpc =
      Visloc({"relocalize", "--server", server.address(), "--map", "square", "--dataset",
              dataset_dir, dataset.frames[0].left_path, "--json"});
  ASSERT_EQ(rpc.exit_code, 0) << rpc.err << rpc.out;
  const ProcessResult session =
      Visloc({"stream", "--server", server.address(), "--map", "square", "--dataset", dataset_dir,
              "--frames", "1", "--rate", "0", "--trajectory", out_.File("first.tum"), "--stats",
              out_.File("first.csv"), "--json"});
  ASSERT_EQ(session.exit_code, 0) << session.err;
  const Trajectory first = ReadTum(out_.File("first.tum"));
  ASSERT_EQ(first.size(), 1u) << "the session's first frame has no pose";
  const Eigen::Vector3d rpc_position(JsonNumber(rpc.out, "tx"), JsonNumber(rpc.out, "ty"),
                                     JsonNumber(rpc.out, "tz"));
  EXPECT_LT((first[0].pose.translation - rpc_position).norm(), 1e-6);
  const Trajectory truth = ReadTum(dataset_dir + "/groundtruth_map.tum");
  ASSERT_FALSE(truth.empty());
  EXPECT_LT((truth[0].pose.translation - rpc_position).norm(), 0.005);
  EXPECT_GT(JsonNumber(rpc.out, "inliers"), 300);
  EXPECT_EQ(JsonNumber(rpc.out, "feature_passes"), 1);  // Found with the tracking features.
  EXPECT_THAT(
      ReadFileBytes(out_.File("first.csv")),
      HasSubstr("," + std::to_string(static_cast<int>(JsonNumber(rpc.out, "inliers"))) + ","));
}

TEST_F(ServerE2eTest, ConcurrentSessionsOnDifferentMaps) {
  std::filesystem::copy_file(kData + "/map.db", maps_.File("square-copy.db"));
  ServerProcess server(VISLOC_SERVER_PATH, maps_.path());
  std::vector<int> pids;
  for (int i = 0; i < 4; ++i) {
    const std::string map = i % 2 ? "square" : "square-copy";
    pids.push_back(testing::SpawnProcess(
        {VISLOC_CLI_PATH, "stream", "--server", server.address(), "--map", map, "--dataset",
         kData + "/query_square", "--frames", "45", "--json"},
        out_.File("stream" + std::to_string(i) + ".json"),
        out_.File("stream" + std::to_string(i) + ".err")));
  }
  for (int i = 0; i < 4; ++i) {
    EXPECT_EQ(testing::WaitProcess(pids[i]), 0);
    std::ifstream in(out_.File("stream" + std::to_string(i) + ".json"));
    const std::string json((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    EXPECT_EQ(JsonNumber(json, "localized_fraction"), 1.0) << json;
    EXPECT_EQ(JsonNumber(json, "errors"), 0);
  }
  server.Stop();
  const std::string log = server.Log();
  EXPECT_EQ(testing::CountOccurrences(log, "event=session_end"), 4u);
  EXPECT_THAT(log, HasSubstr("maps_loaded=2"));
}

TEST_F(ServerE2eTest, ABadFrameMidStreamGetsAnErrorAndTheSessionGoesOn) {
  // A copy of the first 30 frames of the offset square with frame 10 corrupted.
  const std::string dataset = out_.File("broken");
  std::filesystem::copy(kData + "/query_square", dataset, std::filesystem::copy_options::recursive);
  const Dataset original = ReadDataset(dataset);
  const std::string victim = original.frames[10].left_path;
  std::ofstream(victim, std::ios::binary | std::ios::trunc) << "this is not a PNG";
  ServerProcess server(VISLOC_SERVER_PATH, maps_.path());
  const ProcessResult stream =
      Visloc({"stream", "--server", server.address(), "--map", "square", "--dataset", dataset,
              "--frames", "30", "--rate", "0", "--stats", out_.File("s.csv"), "--json"});
  ASSERT_EQ(stream.exit_code, 0) << stream.err;
  EXPECT_EQ(JsonNumber(stream.out, "errors"), 1);
  EXPECT_THAT(stream.err,
              HasSubstr("frame 10: server: image (17 bytes): not a PNG or JPEG image (first bytes "
                        "74 68 69 73)"));
  EXPECT_EQ(JsonNumber(stream.out, "frames"), 29);
  EXPECT_EQ(JsonNumber(stream.out, "localized_fraction"), 1.0);
}

TEST_F(ServerE2eTest, OversizeMessagesAndImagesAreRefusedAndTheServerGoesOn) {
  ServerProcess server(VISLOC_SERVER_PATH, maps_.path());
  auto stub = v1::Localization::NewStub(
      grpc::CreateChannel(server.address(), grpc::InsecureChannelCredentials()));
  const Dataset dataset = ReadDataset(kData + "/query_square");
  const auto start_session = [&](grpc::ClientContext* context) {
    auto stream = stub->Localize(context);
    v1::LocalizeRequest start;
    start.mutable_start()->set_map_name("square");
    proto::ToProto(dataset.left.camera, start.mutable_start()->mutable_camera());
    EXPECT_TRUE(stream->Write(start));
    return stream;
  };
  {
    // A message over the server's 64 MiB limit ends the stream with RESOURCE_EXHAUSTED.
    grpc::ClientContext context;
    auto stream = start_session(&context);
    v1::LocalizeRequest huge;
    huge.mutable_frame()->set_encoded(std::string(65 << 20, '\0'));
    stream->Write(huge);
    stream->WritesDone();
    v1::LocalizeResponse response;
    EXPECT_FALSE(stream->Read(&response));
    EXPECT_EQ(stream->Finish().error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  }
  {
    // A raw frame that claims 5000 x 5000 pixels: an error answer naming the limit, and the
    // session goes on.
    grpc::ClientContext context;
    auto stream = start_session(&context);
    v1::LocalizeRequest frame;
    frame.mutable_frame()->mutable_raw()->set_width(5000);
    frame.mutable_frame()->mutable_raw()->set_height(5000);
    frame.mutable_frame()->mutable_raw()->set_pixels(std::string(1000, '\0'));
    ASSERT_TRUE(stream->Write(frame));
    v1::LocalizeResponse response;
    ASSERT_TRUE(stream->Read(&response));
    EXPECT_EQ(response.status(), v1::STATUS_ERROR);
    EXPECT_THAT(response.error(), HasSubstr("5000"));
    stream->WritesDone();
    EXPECT_TRUE(stream->Finish().ok());
  }
  const ProcessResult next =
      Visloc({"stream", "--server", server.address(), "--map", "square", "--dataset",
              kData + "/query_square", "--frames", "10", "--rate", "0", "--json"});
  EXPECT_EQ(next.exit_code, 0) << next.err;
}

TEST_F(ServerE2eTest, AClientThatVanishesIsCleanedUpAndTheServerGoesOn) {
  ServerProcess server(VISLOC_SERVER_PATH, maps_.path());
  const Dataset dataset = ReadDataset(kData + "/query_square");
  {
    auto stub = v1::Localization::NewStub(
        grpc::CreateChannel(server.address(), grpc::InsecureChannelCredentials()));
    grpc::ClientContext context;
    auto stream = stub->Localize(&context);
    v1::LocalizeRequest start;
    start.mutable_start()->set_map_name("square");
    proto::ToProto(dataset.left.camera, start.mutable_start()->mutable_camera());
    ASSERT_TRUE(stream->Write(start));
    for (int i = 0; i < 5; ++i) {
      v1::LocalizeRequest frame;
      frame.mutable_frame()->set_timestamp_ns(dataset.frames[i].timestamp_ns);
      std::ifstream in(dataset.frames[i].left_path, std::ios::binary);
      frame.mutable_frame()->set_encoded(
          std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>()));
      ASSERT_TRUE(stream->Write(frame));
    }
    v1::LocalizeResponse response;
    ASSERT_TRUE(stream->Read(&response));  // The session is live...
    context.TryCancel();                   // ...and the robot drops off the network.
  }
  ASSERT_TRUE(server.WaitForLog("event=session_end")) << server.Log();
  EXPECT_THAT(server.Log(), HasSubstr("cancelled=true"));
  const ProcessResult next =
      Visloc({"stream", "--server", server.address(), "--map", "square", "--dataset",
              kData + "/query_square", "--frames", "10", "--rate", "0", "--json"});
  EXPECT_EQ(next.exit_code, 0) << next.err;
  EXPECT_THAT(server.Log(), HasSubstr("event=session_start session=2"));
}

// gRPC lets a second server bind a port another already listens on (SO_REUSEPORT), and the
// kernel then shares new connections out between the two at random: a lab that started a server
// twice saw `map list` answer "0 maps" and "2 maps" by turns. A server refuses an address in use.
TEST_F(ServerE2eTest, ASecondServerOnAnAddressInUseIsRefusedByName) {
  ServerProcess first(VISLOC_SERVER_PATH, maps_.path());
  TempDir other_maps;
  // Bounded: a second server that did start would serve until stopped (timeout exits 124).
  const ProcessResult second =
      testing::RunProcess({"/usr/bin/timeout", "10", VISLOC_SERVER_PATH, "--maps",
                           other_maps.path(), "--listen", first.address()});
  EXPECT_EQ(second.exit_code, 1) << second.err;
  EXPECT_THAT(second.err, HasSubstr("cannot listen on " + first.address()));
  EXPECT_THAT(second.err, HasSubstr("in use"));
  // The first one serves on, alone.
  const ProcessResult list = Visloc({"map", "list", "--server", first.address(), "--json"});
  EXPECT_EQ(list.exit_code, 0) << list.err;
}

TEST_F(ServerE2eTest, HealthServiceReportsServing) {
  ServerProcess server(VISLOC_SERVER_PATH, maps_.path());
  auto health = grpc::health::v1::Health::NewStub(
      grpc::CreateChannel(server.address(), grpc::InsecureChannelCredentials()));
  for (const std::string service : {"", "visloc.v1.Localization", "visloc.v1.MapAdmin"}) {
    grpc::ClientContext context;
    grpc::health::v1::HealthCheckRequest request;
    request.set_service(service);
    grpc::health::v1::HealthCheckResponse response;
    ASSERT_TRUE(health->Check(&context, request, &response).ok()) << service;
    EXPECT_EQ(response.status(), grpc::health::v1::HealthCheckResponse::SERVING) << service;
  }
}

TEST_F(ServerE2eTest, SigtermDrainsAnOpenStreamAndExitsCleanly) {
  ServerProcess server(VISLOC_SERVER_PATH, maps_.path());
  // 30 frames at 15 Hz: the stream is open for 2 s; SIGTERM arrives once it is open (however
  // long the client takes to start).
  const int client = testing::SpawnProcess(
      {VISLOC_CLI_PATH, "stream", "--server", server.address(), "--map", "square", "--dataset",
       kData + "/query_square", "--frames", "30", "--json"},
      out_.File("drain.json"), out_.File("drain.err"));
  ASSERT_TRUE(server.WaitForLog("event=session_start"));
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  EXPECT_EQ(server.Stop(), 0);
  EXPECT_EQ(testing::WaitProcess(client), 0);
  std::ifstream in(out_.File("drain.json"));
  const std::string json((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  // Every frame the robot sent was answered before the server went: none undelivered. A loaded
  // machine may make the robot drop frames itself (a real-time camera outrunning its link); they
  // were never sent, so they count apart (a CI run under ASan dropped 2).
  EXPECT_EQ(JsonNumber(json, "frames") + JsonNumber(json, "dropped"), 30) << json;
  EXPECT_GE(JsonNumber(json, "frames"), 15) << json;
  EXPECT_EQ(JsonNumber(json, "undelivered"), 0) << json;
  EXPECT_EQ(JsonNumber(json, "errors"), 0) << json;
  EXPECT_THAT(server.Log(), HasSubstr("event=server_draining signal=SIGTERM open_sessions=1"));
}

TEST_F(ServerE2eTest, BenchMeasuresTheRoundTripThroughTheServer) {
  ServerProcess server(VISLOC_SERVER_PATH, maps_.path());
  const ProcessResult bench = Visloc(
      {"bench", "--dataset", kData + "/query_square", "--map", maps_.File("square.db"), "--frames",
       "10", "--relocalization-queries", "2", "--server", server.address(), "--json"});
  ASSERT_EQ(bench.exit_code, 0) << bench.err;
  EXPECT_GT(JsonNumber(bench.out, "grpc_ms_per_frame_median"), 0.0);
  // The server's own share of the round trip: positive, and less than the whole.
  EXPECT_GT(JsonNumber(bench.out, "grpc_server_ms_per_frame_median"), 0.0);
  EXPECT_LT(JsonNumber(bench.out, "grpc_server_ms_per_frame_median"),
            JsonNumber(bench.out, "grpc_ms_per_frame_median"));
  // Of the server's time, the engine's: positive, and at most all of it.
  EXPECT_GT(JsonNumber(bench.out, "grpc_server_engine_ms_per_frame_median"), 0.0);
  EXPECT_LE(JsonNumber(bench.out, "grpc_server_engine_ms_per_frame_median"),
            JsonNumber(bench.out, "grpc_server_ms_per_frame_median"));
  // The in-process reference, interleaved with the round trips, ran the same frames.
  EXPECT_GT(JsonNumber(bench.out, "grpc_in_process_ms_per_frame_median"), 0.0);
  // The floor: the same bytes, rejected before the engine (no timing comparison here; the
  // machine is shared and noisy, ratios belong to the benchmark report).
  EXPECT_GT(JsonNumber(bench.out, "grpc_no_engine_ms_per_frame_median"), 0.0);
  // The server answered the 10 raw frames of the tracking session, and rejected all 10 of the
  // floor session by their size, each with an answer.
  server.Stop();
  EXPECT_THAT(server.Log(), HasSubstr("map=square frames=10 localized_fraction=1.000 skipped=0 "
                                      "errors=0"));
  EXPECT_THAT(server.Log(), HasSubstr("map=square frames=10 localized_fraction=0.000 skipped=0 "
                                      "errors=10"));
}

TEST(ServerStartTest, RefusesAMissingMapsFolderAndNonLoopbackWithoutAuth) {
  const ProcessResult missing =
      testing::RunProcess({VISLOC_SERVER_PATH, "--maps", "/nonexistent/maps"});
  EXPECT_EQ(missing.exit_code, 1);
  EXPECT_THAT(missing.err, HasSubstr("/nonexistent/maps"));
  TempDir maps;
  const ProcessResult open =
      testing::RunProcess({VISLOC_SERVER_PATH, "--maps", maps.path(), "--listen", "0.0.0.0:0"});
  EXPECT_EQ(open.exit_code, 2);
  EXPECT_THAT(open.err, HasSubstr("loopback only"));
}

}  // namespace
}  // namespace visloc
