// Mapping over the link, end to end: `visloc map build --server` streams the fixture's generated
// stereo run through a link proxy to the real visloc-server, which builds and publishes the map;
// robots then localize in it through the same server. A raw gRPC client does what the CLI never
// does: bad frames, a stream without MappingEnd, a second job, a robot's token.

#include <gmock/gmock.h>
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <thread>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>

#include "core/util/temp_dir.h"
#include "core/util/text_file.h"
#include "dataset/dataset.h"
#include "proto/mapping_convert.h"
#include "tests/support/e2e.h"
#include "tests/support/link_proxy.h"
#include "tests/support/process.h"
#include "visloc/v1/visloc.grpc.pb.h"

namespace visloc {
namespace {

using ::testing::HasSubstr;
using testing::JsonNumber;
using testing::LinkProfile;
using testing::LinkProxy;
using ::testing::Not;
using testing::ProcessResult;
using testing::ServerProcess;
using testing::Visloc;

const std::string kData = VISLOC_LOCALIZATION_DATA;
const std::string kRun = kData + "/map_square";
constexpr int kFrames = 60;  // 12 s of the fixture's 5 Hz walk: a few keyframes, seconds to map.
const std::string kAdminToken = "admin-token-0123456789";
const std::string kRobotToken = "robot-token-0123456789";

// A link a lab's WiFi might give: 10 ms each way, 100 Mbit/s.
const LinkProfile kWifi{10, 2, 100};

// What a folder holds, but the mapping jobs' spool (MAPS/.mapping-jobs: a job's outcome removes
// its folder there, which JobsKept counts).
std::vector<std::string> FilesIn(const std::string& dir) {
  std::vector<std::string> names;
  for (const auto& f : std::filesystem::directory_iterator(dir)) {
    if (f.path().filename() != ".mapping-jobs") names.push_back(f.path().filename().string());
  }
  std::sort(names.begin(), names.end());
  return names;
}

int JobsKept(const std::string& maps_dir) {
  const std::string spool = maps_dir + "/.mapping-jobs";
  int jobs = 0;
  if (!std::filesystem::exists(spool)) return 0;
  for (const auto& f : std::filesystem::directory_iterator(spool)) jobs += f.is_directory();
  return jobs;
}

class MappingLinkE2eTest : public ::testing::Test {
 protected:
  TempDir maps_{"visloc_mapping_link_maps"};
  TempDir work_{"visloc_mapping_link_work"};
};

TEST_F(MappingLinkE2eTest, AStreamedRunBecomesTheMapAnOfflineBuildMakesAndRobotsLocalizeInIt) {
  ServerProcess server(VISLOC_SERVER_PATH, maps_.path());
  LinkProxy link(server.address(), kWifi);
  const std::string frames = "0:" + std::to_string(kFrames);
  const ProcessResult built = Visloc({"map", "build", "--server", link.address(), "--name", "hall",
                                      "--dataset", kRun, "--frames", frames, "--json"});
  ASSERT_EQ(built.exit_code, 0) << built.err;
  EXPECT_EQ(JsonNumber(built.out, "frames"), kFrames);
  EXPECT_EQ(JsonNumber(built.out, "lost_frames"), 0);
  EXPECT_GE(JsonNumber(built.out, "keyframes"), 3);
  EXPECT_TRUE(server.WaitForLog("event=map_built_over_link map=hall"));
  const ProcessResult jobs = Visloc({"jobs", "--server", server.address(), "--json"});
  ASSERT_EQ(jobs.exit_code, 0) << jobs.err;
  EXPECT_THAT(jobs.out, HasSubstr("\"map\":\"hall\",\"robot\":\"visloc-map-build\",\"state\":"
                                  "\"published\",\"running\":false,\"frames\":60,"));

  // The same frames mapped here: the same keyframes (the server decodes the same PNG bytes).
  const ProcessResult offline = Visloc(
      {"map", "build", "--dataset", kRun, "--frames", frames, "--out", work_.File("offline.db")});
  ASSERT_EQ(offline.exit_code, 0) << offline.err;
  ASSERT_EQ(Visloc({"map", "export", maps_.File("hall.db"), "--keyframes", work_.File("link.tum")})
                .exit_code,
            0);
  ASSERT_EQ(
      Visloc({"map", "export", work_.File("offline.db"), "--keyframes", work_.File("offline.tum")})
          .exit_code,
      0);
  const Trajectory over_link = testing::ReadTumLines(work_.File("link.tum"));
  const Trajectory here = testing::ReadTumLines(work_.File("offline.tum"));
  ASSERT_EQ(over_link.size(), here.size());
  for (size_t k = 0; k < here.size(); ++k) {
    EXPECT_EQ(over_link[k].timestamp_ns, here[k].timestamp_ns);
    EXPECT_LT((over_link[k].pose.translation - here[k].pose.translation).norm(), 1e-3)
        << "keyframe " << k;
  }

  // A robot localizes in the published map through the same server.
  const ProcessResult robot = Visloc(
      {"stream", "--server", server.address(), "--map", "hall", "--dataset", kRun, "--frames",
       std::to_string(kFrames), "--rate", "0", "--gt", kRun + "/groundtruth_map.tum", "--json"});
  ASSERT_EQ(robot.exit_code, 0) << robot.err;
  EXPECT_GE(JsonNumber(robot.out, "localized_fraction"), 0.95) << robot.out;

  // A second build of the name is refused without --replace, and the map stays.
  const ProcessResult again = Visloc({"map", "build", "--server", server.address(), "--name",
                                      "hall", "--dataset", kRun, "--frames", "0:5"});
  EXPECT_EQ(again.exit_code, 1);
  EXPECT_THAT(again.err, HasSubstr("a map named 'hall' already exists"));
}

// A rig's disparity correction known from an earlier build reaches the server's builder, which
// maps with it as a build here does, and the published answer reports the one it used.
TEST_F(MappingLinkE2eTest, AKnownDisparityCorrectionIsTheServersToo) {
  ServerProcess server(VISLOC_SERVER_PATH, maps_.path());
  const std::vector<std::string> known = {"--frames", "0:15", "--disparity-correction", "0.2,0.01"};
  std::vector<std::string> remote = {"map",  "build",     "--server", server.address(), "--name",
                                     "hall", "--dataset", kRun,       "--json"};
  remote.insert(remote.end(), known.begin(), known.end());
  const ProcessResult built = Visloc(remote);
  ASSERT_EQ(built.exit_code, 0) << built.err;
  EXPECT_NEAR(JsonNumber(built.out, "disparity_offset_px"), 0.2, 1e-12);
  EXPECT_NEAR(JsonNumber(built.out, "right_camera_yaw_deg"), 0.01, 1e-12);
  std::vector<std::string> here = {"map", "build", "--dataset",
                                   kRun,  "--out", work_.File("offline.db")};
  here.insert(here.end(), known.begin(), known.end());
  ASSERT_EQ(Visloc(here).exit_code, 0);
  for (const auto& [map, tum] : {std::pair{maps_.File("hall.db"), work_.File("link.tum")},
                                 std::pair{work_.File("offline.db"), work_.File("offline.tum")}}) {
    ASSERT_EQ(Visloc({"map", "export", map, "--keyframes", tum}).exit_code, 0);
  }
  const Trajectory over_link = testing::ReadTumLines(work_.File("link.tum"));
  const Trajectory offline = testing::ReadTumLines(work_.File("offline.tum"));
  ASSERT_EQ(over_link.size(), offline.size());
  for (size_t k = 0; k < offline.size(); ++k) {
    EXPECT_LT((over_link[k].pose.translation - offline[k].pose.translation).norm(), 1e-3)
        << "keyframe " << k;
  }
}

// The link is cut for two seconds while frames stream: the client reconnects and resumes the
// job where the server has it, and the map is the one an unbroken run makes.
TEST_F(MappingLinkE2eTest, AShortCutIsResumedAndTheMapIsTheSame) {
  ServerProcess server(VISLOC_SERVER_PATH, maps_.path());
  LinkProxy link(server.address(), kWifi);
  const std::string frames = "0:" + std::to_string(kFrames);
  const int client = testing::SpawnProcess(
      {VISLOC_CLI_PATH, "map", "build", "--server", link.address(), "--name", "hall", "--dataset",
       kRun, "--frames", frames, "--rate", "10", "--json"},
      work_.File("client.out"), work_.File("client.err"));
  ASSERT_TRUE(server.WaitForLog("event=mapping_started map=hall"));
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));  // ~15 frames mapped.
  link.Cut(std::chrono::milliseconds(2000));
  ASSERT_EQ(testing::WaitProcess(client), 0) << ReadFileBytes(work_.File("client.err"));
  const std::string out = ReadFileBytes(work_.File("client.out"));
  EXPECT_GE(JsonNumber(out, "resumes"), 1) << out;
  EXPECT_EQ(JsonNumber(out, "frames"), kFrames) << out;
  EXPECT_TRUE(server.WaitForLog("event=mapping_waiting map=hall"));
  EXPECT_TRUE(server.WaitForLog("event=mapping_resumed map=hall"));

  ASSERT_EQ(Visloc({"map", "build", "--dataset", kRun, "--frames", frames, "--out",
                    work_.File("offline.db")})
                .exit_code,
            0);
  for (const auto& [map, tum] : {std::pair{maps_.File("hall.db"), work_.File("link.tum")},
                                 std::pair{work_.File("offline.db"), work_.File("offline.tum")}}) {
    ASSERT_EQ(Visloc({"map", "export", map, "--keyframes", tum}).exit_code, 0);
  }
  EXPECT_EQ(ReadFileBytes(work_.File("link.tum")), ReadFileBytes(work_.File("offline.tum")));
}

// The link stays down beyond the resume windows: nothing is published, the map of that name that
// was there stays byte for byte, no temporary is left, and the server goes on serving.
TEST_F(MappingLinkE2eTest, ALongCutPublishesNothingAndLeavesTheOldMap) {
  testing::SaveLabMap(maps_.File("hall.db"));
  const std::string before = ReadFileBytes(maps_.File("hall.db"));
  ServerProcess server(VISLOC_SERVER_PATH, maps_.path(), {"--mapping-resume-s", "1"});
  LinkProxy link(server.address(), kWifi);
  const int client =
      testing::SpawnProcess({VISLOC_CLI_PATH, "map", "build", "--server", link.address(), "--name",
                             "hall", "--replace", "--dataset", kRun, "--frames",
                             "0:" + std::to_string(kFrames), "--rate", "10", "--resume-s", "2"},
                            work_.File("client.out"), work_.File("client.err"));
  ASSERT_TRUE(server.WaitForLog("event=mapping_started map=hall"));
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  link.Cut(std::chrono::milliseconds(6000));
  EXPECT_NE(testing::WaitProcess(client), 0);
  const std::string err = ReadFileBytes(work_.File("client.err"));
  EXPECT_THAT(err, HasSubstr("the mapping stream of 'hall' broke and could not be resumed"));
  EXPECT_THAT(err, HasSubstr("nothing was published"));
  ASSERT_TRUE(server.WaitForLog("event=mapping_abandoned map=hall")) << server.Log();
  EXPECT_EQ(ReadFileBytes(maps_.File("hall.db")), before);
  EXPECT_EQ(FilesIn(maps_.path()), std::vector<std::string>{"hall.db"});
  EXPECT_EQ(JobsKept(maps_.path()), 0);  // The abandoned job's spool went with it.
  const ProcessResult jobs = Visloc({"jobs", "--server", server.address()});
  EXPECT_THAT(jobs.out, HasSubstr("abandoned"));
  EXPECT_THAT(jobs.out, HasSubstr("was not resumed within 1 s: nothing was published"));
  const ProcessResult list = Visloc({"map", "list", "--server", server.address(), "--json"});
  EXPECT_EQ(list.exit_code, 0) << list.err;
  EXPECT_THAT(list.out, HasSubstr("\"hall\""));
}

// Two cameras instead of a recording: the run's left and right images as MJPG video files,
// read through OpenCV as a robot's cameras would be.
TEST_F(MappingLinkE2eTest, TwoCamerasAreMappedOverTheLink) {
  const Dataset run = ReadDataset(kRun);
  for (const auto& [side, video] :
       {std::pair{0, work_.File("left.avi")}, std::pair{1, work_.File("right.avi")}}) {
    const Camera& camera = side == 0 ? run.left.camera : run.right->camera;
    cv::VideoWriter writer(video, cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), 5.0,
                           cv::Size(camera.width(), camera.height()), /*isColor=*/false);
    ASSERT_TRUE(writer.isOpened());
    for (int i = 0; i < 40; ++i) {
      writer.write(cv::imread(side == 0 ? run.frames[i].left_path : run.frames[i].right_path,
                              cv::IMREAD_GRAYSCALE));
    }
  }
  ServerProcess server(VISLOC_SERVER_PATH, maps_.path());
  const ProcessResult built =
      Visloc({"map", "build", "--server", server.address(), "--name", "cams", "--camera",
              work_.File("left.avi"), "--camera", work_.File("right.avi"), "--camera-yaml",
              kRun + "/mav0/cam0/sensor.yaml", "--camera-yaml", kRun + "/mav0/cam1/sensor.yaml",
              "--rate", "50", "--json"});
  ASSERT_EQ(built.exit_code, 0) << built.err;
  EXPECT_EQ(JsonNumber(built.out, "frames"), 40);
  EXPECT_GE(JsonNumber(built.out, "keyframes"), 3);
  EXPECT_EQ(JsonNumber(built.out, "lost_frames"), 0);
  EXPECT_TRUE(std::filesystem::exists(maps_.File("cams.db")));

  const ProcessResult one = Visloc({"map", "build", "--server", server.address(), "--name", "x",
                                    "--camera", work_.File("left.avi")});
  EXPECT_EQ(one.exit_code, 2);
  EXPECT_THAT(one.err, HasSubstr("--camera L --camera R with --camera-yaml L.yaml"));
}

// A second run extends the map over the link, as `visloc map extend` extends a file: the run
// is placed in the map and merged, and the map is replaced with the result.
TEST_F(MappingLinkE2eTest, ASecondRunExtendsTheMap) {
  ServerProcess server(VISLOC_SERVER_PATH, maps_.path());
  ASSERT_EQ(Visloc({"map", "build", "--server", server.address(), "--name", "hall", "--dataset",
                    kRun, "--frames", "0:40"})
                .exit_code,
            0);
  const ProcessResult before = Visloc({"map", "info", maps_.File("hall.db"), "--json"});
  const ProcessResult extended =
      Visloc({"map", "build", "--server", server.address(), "--name", "hall", "--extend",
              "--dataset", kRun, "--frames", "30:70", "--json"});
  ASSERT_EQ(extended.exit_code, 0) << extended.err;
  const ProcessResult after = Visloc({"map", "info", maps_.File("hall.db"), "--json"});
  EXPECT_GT(JsonNumber(after.out, "keyframes"), JsonNumber(before.out, "keyframes"));
  EXPECT_THAT(after.out, HasSubstr("lineage"));
  EXPECT_THAT(after.out, Not(HasSubstr("\"lineage\":\"\"")));
  const ProcessResult missing = Visloc({"map", "build", "--server", server.address(), "--name",
                                        "nowhere", "--extend", "--dataset", kRun, "--frames", "5"});
  EXPECT_EQ(missing.exit_code, 1);
  EXPECT_THAT(missing.err, HasSubstr("no map named 'nowhere' to extend"));
}

// A job is bounded in memory: frames beyond the bound are refused by name, and the run so far
// is still published when it ends.
TEST_F(MappingLinkE2eTest, FramesBeyondAJobsMemoryAreRefusedAndTheRunSoFarPublished) {
  ServerProcess server(VISLOC_SERVER_PATH, maps_.path(), {"--max-mapping-memory-mib", "1"});
  const ProcessResult built = Visloc({"map", "build", "--server", server.address(), "--name",
                                      "small", "--dataset", kRun, "--frames", "0:30", "--json"});
  ASSERT_EQ(built.exit_code, 0) << built.err;
  EXPECT_GT(JsonNumber(built.out, "refused_frames"), 5) << built.out;
  EXPECT_LT(JsonNumber(built.out, "refused_frames"), 30) << built.out;
  const ProcessResult text = Visloc({"map", "build", "--server", server.address(), "--name",
                                     "small", "--replace", "--dataset", kRun, "--frames", "0:30"});
  EXPECT_THAT(text.out, HasSubstr("(--max-mapping-memory-mib 1); end the stream to publish"));
  EXPECT_TRUE(std::filesystem::exists(maps_.File("small.db")));
}

TEST_F(MappingLinkE2eTest, TheCommandSaysWhereTheMapGoes) {
  const ProcessResult nameless =
      Visloc({"map", "build", "--dataset", kRun, "--server", "127.0.0.1:1"});
  EXPECT_EQ(nameless.exit_code, 2);
  EXPECT_THAT(nameless.err, HasSubstr("--server needs --name"));
  const ProcessResult both = Visloc({"map", "build", "--dataset", kRun, "--server", "127.0.0.1:1",
                                     "--name", "x", "--out", work_.File("x.db")});
  EXPECT_EQ(both.exit_code, 2);
  EXPECT_THAT(both.err, HasSubstr("give --out MAP.db (build here) or --server ADDR --name NAME"));
  const ProcessResult trajectory =
      Visloc({"map", "build", "--dataset", kRun, "--server", "127.0.0.1:1", "--name", "x",
              "--trajectory", work_.File("t.tum")});
  EXPECT_EQ(trajectory.exit_code, 2);
  EXPECT_THAT(trajectory.err,
              HasSubstr("--trajectory, --max-features and --rig-error are for builds here (--out)"));
  const ProcessResult rig_error =
      Visloc({"map", "build", "--dataset", kRun, "--server", "127.0.0.1:1", "--name", "x",
              "--rig-error", "0,0"});
  EXPECT_EQ(rig_error.exit_code, 2);
  EXPECT_THAT(rig_error.err,
              HasSubstr("--trajectory, --max-features and --rig-error are for builds here (--out)"));
}

// What the CLI never sends, from a raw gRPC client.
class MappingServiceE2eTest : public MappingLinkE2eTest {
 protected:
  void SetUp() override {
    std::ofstream(work_.File("tokens")) << kRobotToken << " localize\n"
                                        << kAdminToken << " admin\n";
    server_ =
        std::make_unique<ServerProcess>(VISLOC_SERVER_PATH, maps_.path(),
                                        std::vector<std::string>{"--tokens", work_.File("tokens")});
    run_ = ReadDataset(kRun);
  }
  using Stream = grpc::ClientReaderWriter<v1::MappingRequest, v1::MappingProgress>;
  struct Call {
    grpc::ClientContext context;
    std::unique_ptr<Stream> stream;
  };
  std::unique_ptr<Call> Open(const std::string& token = kAdminToken) {
    auto call = std::make_unique<Call>();
    call->context.AddMetadata("authorization", "Bearer " + token);
    call->stream = v1::Mapping::NewStub(
                       grpc::CreateChannel(server_->address(), grpc::InsecureChannelCredentials()))
                       ->BuildMap(&call->context);
    return call;
  }
  v1::MappingRequest Start(const std::string& name) const {
    v1::MappingRequest request;
    request.mutable_start()->set_map_name(name);
    proto::ToProto(run_.left.camera, run_.right->camera, run_.left.body_from_cam,
                   run_.right->body_from_cam, request.mutable_start()->mutable_rig());
    return request;
  }
  v1::MappingRequest Frame(int i) const {
    v1::MappingRequest request;
    request.mutable_frame()->set_timestamp_ns(run_.frames[i].timestamp_ns);
    request.mutable_frame()->set_left_encoded(ReadFileBytes(run_.frames[i].left_path));
    request.mutable_frame()->set_right_encoded(ReadFileBytes(run_.frames[i].right_path));
    return request;
  }
  // Sends `request` and reads its answer.
  static v1::MappingProgress Exchange(Stream* stream, const v1::MappingRequest& request) {
    v1::MappingProgress answer;
    EXPECT_TRUE(stream->Write(request));
    EXPECT_TRUE(stream->Read(&answer));
    return answer;
  }

  std::unique_ptr<ServerProcess> server_;
  Dataset run_;
};

TEST_F(MappingServiceE2eTest, BadFramesAreAnsweredByNameAndTheJobGoesOn) {
  auto call = Open();
  const v1::MappingProgress started = Exchange(call->stream.get(), Start("bad_frames"));
  EXPECT_EQ(started.state(), v1::MAPPING_STARTED);
  EXPECT_GT(started.job_id(), 0u);
  EXPECT_EQ(Exchange(call->stream.get(), Frame(0)).state(), v1::MAPPING_TRACKING);

  v1::MappingRequest garbage = Frame(1);
  garbage.mutable_frame()->set_left_encoded("not an image");
  const v1::MappingProgress refused = Exchange(call->stream.get(), garbage);
  EXPECT_EQ(refused.state(), v1::MAPPING_FRAME_ERROR);
  EXPECT_THAT(refused.error(), HasSubstr("left image (12 bytes): not a PNG or JPEG image"));

  v1::MappingRequest small = Frame(1);
  small.mutable_frame()->clear_right_encoded();
  v1::RawImage* raw = small.mutable_frame()->mutable_right_raw();
  raw->set_width(10);
  raw->set_height(10);
  raw->set_pixels(std::string(100, '\x80'));
  EXPECT_THAT(Exchange(call->stream.get(), small).error(),
              HasSubstr("right image is 10x10 but the session camera is"));

  EXPECT_THAT(Exchange(call->stream.get(), Frame(0)).error(), HasSubstr("is not after the last"));
  const v1::MappingProgress next = Exchange(call->stream.get(), Frame(1));
  EXPECT_EQ(next.state(), v1::MAPPING_TRACKING);
  EXPECT_EQ(next.frame_index(), 4u);
  EXPECT_TRUE(next.has_pose());
  EXPECT_GT(next.tracked(), 50u);

  // The stream ends without MappingEnd: nothing is published, and the job waits to be resumed.
  call->stream->WritesDone();
  const grpc::Status status = call->stream->Finish();
  EXPECT_EQ(status.error_code(), grpc::StatusCode::ABORTED);
  EXPECT_THAT(status.error_message(), HasSubstr("waits 30 s to be resumed"));
  EXPECT_TRUE(FilesIn(maps_.path()).empty());

  // Resuming another map's job is refused; resuming this one answers where it stands.
  v1::MappingRequest resume = Start("other_name");
  resume.mutable_start()->set_resume_job_id(next.job_id());
  auto wrong = Open();
  wrong->stream->Write(resume);
  wrong->stream->WritesDone();
  EXPECT_EQ(wrong->stream->Finish().error_code(), grpc::StatusCode::NOT_FOUND);
  resume.mutable_start()->set_map_name("bad_frames");
  auto again = Open();
  ASSERT_TRUE(again->stream->Write(resume));
  v1::MappingProgress resumed;
  ASSERT_TRUE(again->stream->Read(&resumed));
  EXPECT_EQ(resumed.state(), v1::MAPPING_RESUMED);
  EXPECT_EQ(resumed.job_id(), next.job_id());
  EXPECT_EQ(resumed.timestamp_ns(), run_.frames[1].timestamp_ns);  // The last frame mapped.
  EXPECT_EQ(resumed.frame_index(), 5u);                            // Frames that arrived.
  const v1::MappingProgress after = Exchange(again->stream.get(), Frame(2));
  EXPECT_EQ(after.state(), v1::MAPPING_TRACKING);
  EXPECT_EQ(after.frame_index(), 5u);
  again->context.TryCancel();
}

// Without a resume window a broken job is abandoned at once and its slot freed.
TEST_F(MappingServiceE2eTest, WithoutAResumeWindowABrokenJobIsAbandonedAtOnce) {
  server_ = std::make_unique<ServerProcess>(
      VISLOC_SERVER_PATH, maps_.path(),
      std::vector<std::string>{"--tokens", work_.File("tokens"), "--mapping-resume-s", "0"});
  auto call = Open();
  ASSERT_EQ(Exchange(call->stream.get(), Start("gone")).state(), v1::MAPPING_STARTED);
  EXPECT_EQ(Exchange(call->stream.get(), Frame(0)).state(), v1::MAPPING_TRACKING);
  call->stream->WritesDone();
  const grpc::Status status = call->stream->Finish();
  EXPECT_EQ(status.error_code(), grpc::StatusCode::ABORTED);
  EXPECT_THAT(status.error_message(), HasSubstr("(no MappingEnd): nothing was published"));
  auto next = Open();  // The slot is free again.
  EXPECT_EQ(Exchange(next->stream.get(), Start("next")).state(), v1::MAPPING_STARTED);
  next->context.TryCancel();
  EXPECT_TRUE(FilesIn(maps_.path()).empty());
  EXPECT_TRUE(testing::WaitUntil([&] { return JobsKept(maps_.path()) == 0; }));  // Both abandoned.
}

TEST_F(MappingServiceE2eTest, OneJobAtATimeAdminsOnlyAndSmallMapsAreNotPublished) {
  auto robot = Open(kRobotToken);
  robot->stream->Write(Start("robot_map"));
  robot->stream->WritesDone();
  EXPECT_EQ(robot->stream->Finish().error_code(), grpc::StatusCode::PERMISSION_DENIED);

  auto first = Open();
  ASSERT_EQ(Exchange(first->stream.get(), Start("tiny")).state(), v1::MAPPING_STARTED);
  EXPECT_EQ(Exchange(first->stream.get(), Frame(0)).state(), v1::MAPPING_TRACKING);
  auto second = Open();
  second->stream->Write(Start("other"));
  second->stream->WritesDone();
  const grpc::Status busy = second->stream->Finish();
  EXPECT_EQ(busy.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_THAT(busy.error_message(), HasSubstr("--max-mapping-jobs"));

  // One stereo frame of the room is a map of its stereo points.
  v1::MappingRequest end;
  end.mutable_end();
  ASSERT_TRUE(first->stream->Write(end));
  first->stream->WritesDone();
  v1::MappingProgress answer, last;
  while (first->stream->Read(&answer)) last = answer;
  EXPECT_EQ(first->stream->Finish().error_code(), grpc::StatusCode::OK);
  EXPECT_EQ(last.state(), v1::MAPPING_PUBLISHED);
  EXPECT_EQ(last.map().name(), "tiny");
  EXPECT_EQ(last.keyframes(), 1u);
  EXPECT_GT(last.points(), 100u);
  EXPECT_EQ(FilesIn(maps_.path()), std::vector<std::string>{"tiny.db"});

  // A map smaller than asked for is not published.
  auto strict = Open();
  v1::MappingRequest start = Start("strict");
  start.mutable_start()->mutable_options()->set_min_points(100000);
  ASSERT_EQ(Exchange(strict->stream.get(), start).state(), v1::MAPPING_STARTED);
  EXPECT_EQ(Exchange(strict->stream.get(), Frame(0)).state(), v1::MAPPING_TRACKING);
  ASSERT_TRUE(strict->stream->Write(end));
  strict->stream->WritesDone();
  while (strict->stream->Read(&answer)) last = answer;
  const grpc::Status refused = strict->stream->Finish();
  EXPECT_EQ(refused.error_code(), grpc::StatusCode::FAILED_PRECONDITION);
  EXPECT_EQ(last.state(), v1::MAPPING_FAILED);
  EXPECT_THAT(last.error(), HasSubstr("fewer than 100000 (min_points)"));
  EXPECT_EQ(FilesIn(maps_.path()), std::vector<std::string>{"tiny.db"});
}

}  // namespace
}  // namespace visloc
