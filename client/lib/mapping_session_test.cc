// The client library's mapping session against the real Mapping service on a loopback port (in
// process): a rendered stereo run sent as images (encoded by the library) becomes a published
// map, every frame answered in order; a refused job throws with the server's reason. Link cuts
// and resumption are end-to-end tests (tests/mapping_link_e2e_test.cc).

#include "visloc/client/mapping_session.h"

#include <gmock/gmock.h>
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <filesystem>

#include "core/util/temp_dir.h"
#include "dataset/dataset.h"
#include "proto/mapping_convert.h"
#include "server/mapping_service.h"
#include "sim/generate.h"

namespace visloc::client {
namespace {

using ::testing::HasSubstr;

class MappingSessionTest : public ::testing::Test {
 protected:
  void SetUp() override {
    sim::GenerateOptions generate;
    generate.max_frames = 12;
    generate.contact_sheet = false;
    run_ = ReadDataset(
        sim::SequenceGenerator(generate).Generate("map_square", frames_dir_.path()).dir);
    maps_ = std::make_unique<server::MapCache>(maps_dir_.path(), std::chrono::seconds(60));
    service_ =
        std::make_unique<server::MappingService>(maps_.get(), server::MappingLimits{}, &auth_);
    grpc::ServerBuilder builder;
    builder.AddListeningPort("127.0.0.1:0", grpc::InsecureServerCredentials(), &port_);
    builder.RegisterService(service_.get());
    server_ = builder.BuildAndStart();
    ASSERT_GT(port_, 0);
  }
  void TearDown() override { server_->Shutdown(); }

  MappingSessionOptions Options(const std::string& name) const {
    MappingSessionOptions o;
    o.server = "127.0.0.1:" + std::to_string(port_);
    o.map_name = name;
    o.robot_id = "test-robot";
    proto::ToProto(run_.left.camera, run_.right->camera, run_.left.body_from_cam,
                   run_.right->body_from_cam, &o.rig);
    return o;
  }
  StereoFrame Frame(size_t i) const {
    StereoFrame frame;
    frame.timestamp_ns = run_.frames[i].timestamp_ns;
    frame.left = LoadGreyImage(run_.frames[i].left_path, 0, 0);
    frame.right = LoadGreyImage(run_.frames[i].right_path, 0, 0);
    return frame;
  }

  TempDir frames_dir_{"visloc-mapping-session-frames"};
  TempDir maps_dir_{"visloc-mapping-session-maps"};
  Dataset run_;
  const server::TokenAuth auth_;
  std::unique_ptr<server::MapCache> maps_;
  std::unique_ptr<server::MappingService> service_;
  std::unique_ptr<grpc::Server> server_;
  int port_ = 0;
};

TEST_F(MappingSessionTest, ARunOfImagesBecomesAPublishedMapEveryFrameAnsweredInOrder) {
  auto session = MappingSession::Open(Options("hall"));
  EXPECT_GT(session->job_id(), 0u);
  std::vector<MappingAnswer> answers;
  for (size_t i = 0; i < run_.frames.size(); ++i) {
    std::string why;
    ASSERT_TRUE(session->Submit(Frame(i), &why)) << why;
    for (MappingAnswer& a : session->TakeAnswers()) answers.push_back(a);
  }
  const v1::MappingProgress published = session->Finish();
  for (MappingAnswer& a : session->TakeAnswers()) answers.push_back(a);
  EXPECT_EQ(published.state(), v1::MAPPING_PUBLISHED);
  EXPECT_EQ(published.map().name(), "hall");
  EXPECT_EQ(published.frame_index(), run_.frames.size());
  EXPECT_GE(published.keyframes(), 1u);
  EXPECT_TRUE(std::filesystem::exists(maps_dir_.File("hall.db")));
  ASSERT_EQ(answers.size(), run_.frames.size());
  for (size_t i = 0; i < answers.size(); ++i) {
    EXPECT_EQ(answers[i].progress.state(), v1::MAPPING_TRACKING) << answers[i].progress.error();
    EXPECT_EQ(answers[i].progress.timestamp_ns(), run_.frames[i].timestamp_ns);
    EXPECT_GT(answers[i].latency_ms, 0.0);
  }
  const MappingSessionStats stats = session->stats();
  EXPECT_EQ(stats.submitted, run_.frames.size());
  EXPECT_EQ(stats.answered, run_.frames.size());
  EXPECT_EQ(stats.resumes, 0u);
  EXPECT_GT(stats.bytes_sent, 0u);
}

TEST_F(MappingSessionTest, RefusedJobsAndBadOptionsSayWhy) {
  MappingSessionOptions options = Options("hall");
  options.max_in_flight = 0;
  EXPECT_THROW(MappingSession::Open(options), std::invalid_argument);
  options = Options("bad/name");
  try {
    MappingSession::Open(options);
    ADD_FAILURE() << "a bad map name was taken";
  } catch (const std::runtime_error& e) {
    EXPECT_THAT(e.what(), HasSubstr("gRPC code 3"));  // INVALID_ARGUMENT
  }
}

}  // namespace
}  // namespace visloc::client
