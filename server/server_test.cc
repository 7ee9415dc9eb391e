#include "server/server.h"

#include <gmock/gmock.h>
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include "core/util/args.h"
#include "core/util/check.h"
#include "core/util/temp_dir.h"
#include "server/test_session.h"

namespace visloc::server {
namespace {

using ::testing::HasSubstr;

// The composition root on a loopback port over a folder with one small map, "lab".
class ServerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    testing::WriteLabMap(maps_dir_.path());
    config_.maps_dir = maps_dir_.path();
    config_.listen = "127.0.0.1:0";
    config_.threads = 1;
  }

  TempDir maps_dir_{"visloc_server_test"};
  ServerConfig config_;
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
  ASSERT_TRUE(stream->Write(testing::StartRequest(v1::PROCESS_ALL, "rover-7")));
  for (int i = 0; i < 3; ++i) {
    ASSERT_TRUE(stream->Write(testing::FrameRequest(i)));
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
  config.http = "0.0.0.0:8080";  // The page and metrics would be open to the network.
  EXPECT_THAT(refusal(config), HasSubstr("--allow-remote"));
  config = config_;
  config.tls_cert = "cert.pem";
  EXPECT_THAT(refusal(config), HasSubstr("--tls-cert and --tls-key go together"));
  config = config_;
  config.max_upload_mib = 0;
  EXPECT_THAT(refusal(config), HasSubstr("--max-upload-mib"));
  config = config_;
  config.keepalive_time_s = -1;
  EXPECT_THAT(refusal(config), HasSubstr("--keepalive-time-s"));
  EXPECT_EQ(refusal(config_), "accepted");
}

}  // namespace
}  // namespace visloc::server
