#include "server/server.h"

#include <gmock/gmock.h>
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include "core/map/synthetic_map.h"
#include "core/util/args.h"
#include "core/util/check.h"
#include "core/util/temp_dir.h"
#include "mapstore/map_store.h"
#include "proto/geometry_convert.h"

namespace visloc::server {
namespace {

using ::testing::HasSubstr;

// The composition root on a loopback port over a folder with one small map, "lab".
class ServerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    SyntheticMapOptions options;
    options.keyframes = 6;
    options.points = 300;
    Map map = MakeSyntheticMap(options);
    map.metadata.name = "lab";
    mapstore::SaveMap(map, maps_dir_.File("lab.db"));
    config_.maps_dir = maps_dir_.path();
    config_.listen = "127.0.0.1:0";
    config_.threads = 1;
  }

  TempDir maps_dir_{"visloc_server_test"};
  ServerConfig config_;
  const Camera camera_{160, 120, 80.0, 80.0, 79.5, 59.5};
};

// What a session does is in the status while it runs, and gone when it ends: the snapshot the
// operator's page and metrics will read.
TEST_F(ServerTest, TheStatusListsALiveSessionAndItsMap) {
  Server server(config_);
  EXPECT_THAT(server.address(), ::testing::StartsWith("127.0.0.1:"));
  EXPECT_NE(server.address(), "127.0.0.1:0");
  EXPECT_TRUE(server.Status().sessions.empty());

  auto channel = grpc::CreateChannel(server.address(), grpc::InsecureChannelCredentials());
  grpc::ClientContext context;
  auto stream = v1::Localization::NewStub(channel)->Localize(&context);
  v1::LocalizeRequest start;
  start.mutable_start()->set_map_name("lab");
  start.mutable_start()->set_robot_id("rover-7");
  proto::ToProto(camera_, start.mutable_start()->mutable_camera());
  ASSERT_TRUE(stream->Write(start));
  for (int i = 0; i < 3; ++i) {
    v1::LocalizeRequest frame;
    frame.mutable_frame()->set_timestamp_ns((i + 1) * 50'000'000LL);
    v1::RawImage* raw = frame.mutable_frame()->mutable_raw();
    raw->set_width(camera_.width());
    raw->set_height(camera_.height());
    raw->set_pixels(std::string(camera_.width() * camera_.height(), '\x60'));
    ASSERT_TRUE(stream->Write(frame));
    v1::LocalizeResponse response;
    ASSERT_TRUE(stream->Read(&response));
  }
  ServerStatus status = server.Status();
  ASSERT_EQ(status.sessions.size(), 1u);
  EXPECT_EQ(status.sessions[0].id, 1u);
  EXPECT_EQ(status.sessions[0].map, "lab");
  EXPECT_EQ(status.sessions[0].robot_id, "rover-7");
  EXPECT_EQ(status.sessions[0].frames, 3u);
  EXPECT_EQ(status.sessions[0].errors, 0u);
  EXPECT_FALSE(status.sessions[0].has_pose);  // A grey frame shows nothing of the map.
  ASSERT_EQ(status.maps.size(), 1u);
  EXPECT_EQ(status.maps[0].name, "lab");
  EXPECT_EQ(status.maps[0].users, 1);
  EXPECT_GT(status.maps[0].memory_bytes, 0u);
  EXPECT_EQ(status.map_loads, 1);
  EXPECT_EQ(status.workers, 1);
  EXPECT_EQ(status.workers_peak, 1);
  EXPECT_EQ(status.max_sessions, 64);

  stream->WritesDone();
  EXPECT_TRUE(stream->Finish().ok());
  status = server.Status();
  EXPECT_TRUE(status.sessions.empty());
  EXPECT_EQ(status.maps[0].users, 0);
  server.Drain();
}

TEST_F(ServerTest, ASecondServerOnTheSameAddressIsRefused) {
  Server first(config_);
  ServerConfig second = config_;
  second.listen = first.address();
  try {
    Server again(second);
    FAIL() << "two servers listen on " << first.address();
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("the address is in use"));
  }
}

TEST_F(ServerTest, ABadConfigIsRefusedNamingTheFlag) {
  const auto refusal = [](const ServerConfig& config) {
    try {
      config.Check();
    } catch (const UsageError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  ServerConfig config = config_;
  config.listen = "0.0.0.0:0";
  EXPECT_THAT(refusal(config), HasSubstr("--allow-remote"));
  config = config_;
  config.tls_cert = "cert.pem";
  EXPECT_THAT(refusal(config), HasSubstr("--tls-cert and --tls-key go together"));
  config = config_;
  config.max_upload_mib = 0;
  EXPECT_THAT(refusal(config), HasSubstr("--max-upload-mib"));
  config = config_;
  config.keepalive_time_s = -1;
  EXPECT_THAT(refusal(config), HasSubstr("--keepalive-time"));
  EXPECT_EQ(refusal(config_), "accepted");
}

}  // namespace
}  // namespace visloc::server
