// Security end to end against the real server: bearer tokens with two roles (robots localize,
// admins manage maps), TLS, and mutual TLS with certificates generated for the test by openssl.

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <opencv2/core.hpp>

#include <filesystem>
#include <fstream>

#include "core/image/image_codec.h"
#include "core/map/synthetic_map.h"
#include "core/util/temp_dir.h"
#include "mapstore/map_store.h"
#include "tests/support/e2e.h"
#include "tests/support/process.h"

namespace visloc {
namespace {

using ::testing::HasSubstr;
using testing::JsonNumber;
using testing::ProcessResult;
using testing::ServerProcess;
using testing::Visloc;

const std::string kRobotToken = "robot-token-0123456789";
const std::string kAdminToken = "admin-token-0123456789";

class SecurityE2eTest : public ::testing::Test {
 protected:
  void SetUp() override {
    SyntheticMapOptions options;
    options.keyframes = 10;
    options.points = 500;
    mapstore::SaveMap(MakeSyntheticMap(options), maps_.File("lab.db"));
    std::ofstream(files_.File("tokens")) << "# robots and operators\n"
                                         << kRobotToken << " localize\n"
                                         << kAdminToken << " admin\n";
    std::string error;
    EXPECT_TRUE(image::WritePng(files_.File("blank.png"),
                                cv::Mat(240, 320, CV_8UC1, cv::Scalar(128)), 1, &error))
        << error;
  }
  TempDir maps_{"visloc_security_maps"};
  TempDir files_{"visloc_security_files"};
};

TEST_F(SecurityE2eTest, TokenRolesAreEnforcedOnEveryService) {
  ServerProcess server(VISLOC_SERVER_PATH, maps_.path(), {"--tokens", files_.File("tokens")});
  const std::string address = server.address();
  const ProcessResult missing = Visloc({"map", "list", "--server", address});
  EXPECT_EQ(missing.exit_code, 1);
  // The way out is named: the CLI's flag and variable.
  EXPECT_THAT(missing.err,
              HasSubstr("missing bearer token: give visloc --token TOKEN or $VISLOC_TOKEN"));
  EXPECT_THAT(missing.err, HasSubstr("gRPC code 16"));  // UNAUTHENTICATED
  const ProcessResult wrong =
      Visloc({"map", "list", "--server", address, "--token", "nope-nope-nope-nope"});
  EXPECT_EQ(wrong.exit_code, 1);
  EXPECT_THAT(wrong.err, HasSubstr("unknown token"));
  const ProcessResult robot_admin =
      Visloc({"map", "delete", "lab", "--server", address, "--token", kRobotToken});
  EXPECT_EQ(robot_admin.exit_code, 1);
  EXPECT_THAT(robot_admin.err, HasSubstr("may localize but not manage maps"));
  EXPECT_THAT(robot_admin.err, HasSubstr("gRPC code 7"));  // PERMISSION_DENIED
  EXPECT_TRUE(std::filesystem::exists(maps_.File("lab.db")));

  // Localization: refused without a token, served with the robot's (a blank image is simply
  // not localized: exit 3, not an authorization error).
  const ProcessResult anonymous =
      Visloc({"relocalize", "--server", address, "--map", "lab", files_.File("blank.png")});
  EXPECT_EQ(anonymous.exit_code, 1);
  EXPECT_THAT(anonymous.err, HasSubstr("missing bearer token"));
  const ProcessResult robot = Visloc({"relocalize", "--server", address, "--map", "lab",
                                      files_.File("blank.png"), "--token", kRobotToken});
  EXPECT_EQ(robot.exit_code, 3) << robot.err;
  EXPECT_THAT(robot.out, HasSubstr("not localized"));

  const ProcessResult admin = Visloc({"map", "list", "--server", address, "--token", kAdminToken});
  EXPECT_EQ(admin.exit_code, 0) << admin.err;
  EXPECT_THAT(admin.out, HasSubstr("lab"));
  EXPECT_EQ(Visloc({"map", "delete", "lab", "--server", address, "--token", kAdminToken}).exit_code,
            0);
}

TEST_F(SecurityE2eTest, MalformedTokenFilesAreRefusedAtStart) {
  std::ofstream(files_.File("bad_tokens")) << kRobotToken << " superuser\n";
  const ProcessResult bad = testing::RunProcess(
      {VISLOC_SERVER_PATH, "--maps", maps_.path(), "--tokens", files_.File("bad_tokens")});
  EXPECT_EQ(bad.exit_code, 1);
  EXPECT_THAT(bad.err, HasSubstr(files_.File("bad_tokens") + ":1: expected 'TOKEN ROLE'"));
}

TEST_F(SecurityE2eTest, TlsServesOnlyClientsThatTrustItsCertificate) {
  const std::string key = files_.File("server.key"), cert = files_.File("server.pem");
  const ProcessResult openssl =
      testing::RunProcess({"/usr/bin/openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes",
                           "-keyout", key, "-out", cert, "-days", "1", "-subj", "/CN=localhost",
                           "-addext", "subjectAltName=IP:127.0.0.1,DNS:localhost"});
  ASSERT_EQ(openssl.exit_code, 0) << openssl.err;
  ServerProcess server(VISLOC_SERVER_PATH, maps_.path(), {"--tls-cert", cert, "--tls-key", key});
  const ProcessResult trusted =
      Visloc({"map", "list", "--server", server.address(), "--tls-ca", cert});
  EXPECT_EQ(trusted.exit_code, 0) << trusted.err;
  EXPECT_THAT(trusted.out, HasSubstr("lab"));
  const ProcessResult plaintext = Visloc({"map", "list", "--server", server.address()});
  EXPECT_EQ(plaintext.exit_code, 1);
  EXPECT_THAT(plaintext.err, HasSubstr("gRPC code 14"));  // UNAVAILABLE: no TLS handshake
  EXPECT_THAT(server.Log(), HasSubstr("tls=on"));
}

TEST_F(SecurityE2eTest, RobotTokensCannotCallAnyMapAdminRpc) {
  ServerProcess server(VISLOC_SERVER_PATH, maps_.path(), {"--tokens", files_.File("tokens")});
  const std::string a = server.address();
  const std::vector<std::vector<std::string>> admin_calls = {
      {"map", "list", "--server", a},
      {"map", "info", "lab", "--server", a},
      {"map", "upload", maps_.File("lab.db"), "--name", "copy", "--server", a},
      {"map", "download", "lab", "--out", files_.File("lab.db"), "--server", a},
      {"map", "rename", "lab", "other", "--server", a},
      {"map", "delete", "lab", "--server", a}};
  for (std::vector<std::string> call : admin_calls) {
    call.insert(call.end(), {"--token", kRobotToken});
    const ProcessResult result = Visloc(call);
    EXPECT_EQ(result.exit_code, 1) << call[1];
    EXPECT_THAT(result.err, HasSubstr("gRPC code 7")) << call[1];  // PERMISSION_DENIED
  }
  EXPECT_TRUE(std::filesystem::exists(maps_.File("lab.db")));
  EXPECT_FALSE(std::filesystem::exists(maps_.File("copy.db")));
  EXPECT_FALSE(std::filesystem::exists(files_.File("lab.db")));
}

// openssl, as an operator would run it (absolute path: the test runs it without a shell).
void OpenSsl(const std::vector<std::string>& args) {
  std::vector<std::string> command = {"/usr/bin/openssl"};
  command.insert(command.end(), args.begin(), args.end());
  const ProcessResult result = testing::RunProcess(command);
  ASSERT_EQ(result.exit_code, 0) << result.err;
}

TEST_F(SecurityE2eTest, MutualTlsServesOnlyClientsWithACertificateFromTheClientCa) {
  const auto file = [&](const char* name) { return files_.File(name); };
  const std::vector<std::string> self_signed = {"req",    "-x509", "-newkey", "rsa:2048",
                                                "-nodes", "-days", "1"};
  auto with = [](std::vector<std::string> base, std::vector<std::string> more) {
    base.insert(base.end(), more.begin(), more.end());
    return base;
  };
  OpenSsl(
      with(self_signed, {"-keyout", file("server.key"), "-out", file("server.pem"), "-subj",
                         "/CN=localhost", "-addext", "subjectAltName=IP:127.0.0.1,DNS:localhost"}));
  OpenSsl(with(self_signed, {"-keyout", file("ca.key"), "-out", file("ca.pem"), "-subj",
                             "/CN=visloc robots CA"}));
  OpenSsl({"req", "-newkey", "rsa:2048", "-nodes", "-keyout", file("robot.key"), "-out",
           file("robot.csr"), "-subj", "/CN=robot-7"});
  OpenSsl({"x509", "-req", "-in", file("robot.csr"), "-CA", file("ca.pem"), "-CAkey",
           file("ca.key"), "-CAcreateserial", "-out", file("robot.pem"), "-days", "1"});
  OpenSsl(with(self_signed,
               {"-keyout", file("rogue.key"), "-out", file("rogue.pem"), "-subj", "/CN=rogue"}));

  ServerProcess server(VISLOC_SERVER_PATH, maps_.path(),
                       {"--tls-cert", file("server.pem"), "--tls-key", file("server.key"),
                        "--tls-client-ca", file("ca.pem")});
  const std::vector<std::string> list = {
      "map", "list", "--server", server.address(), "--tls-ca", file("server.pem")};
  const ProcessResult robot =
      Visloc(with(list, {"--tls-cert", file("robot.pem"), "--tls-key", file("robot.key")}));
  EXPECT_EQ(robot.exit_code, 0) << robot.err;
  EXPECT_THAT(robot.out, HasSubstr("lab"));
  const ProcessResult no_certificate = Visloc(list);
  EXPECT_EQ(no_certificate.exit_code, 1);
  EXPECT_THAT(no_certificate.err, HasSubstr("gRPC code 14"));  // handshake refused
  const ProcessResult rogue =
      Visloc(with(list, {"--tls-cert", file("rogue.pem"), "--tls-key", file("rogue.key")}));
  EXPECT_EQ(rogue.exit_code, 1);
  EXPECT_THAT(rogue.err, HasSubstr("gRPC code 14"));
  const ProcessResult half = Visloc(with(list, {"--tls-cert", file("robot.pem")}));
  EXPECT_EQ(half.exit_code, 2);
  EXPECT_THAT(half.err, HasSubstr("--tls-cert and --tls-key go together"));
  EXPECT_THAT(server.Log(), HasSubstr("tls=mutual"));

  // A robot's session through the client library over the same mutual TLS: answered.
  const ProcessResult sim = Visloc({"sim", "--out", file("seq"), "--sequence", "query_square",
                                    "--frames", "5", "--no-contact-sheet"});
  ASSERT_EQ(sim.exit_code, 0) << sim.err;
  const std::vector<std::string> stream = {"stream",
                                           "--server",
                                           server.address(),
                                           "--tls-ca",
                                           file("server.pem"),
                                           "--map",
                                           "lab",
                                           "--dataset",
                                           file("seq") + "/query_square",
                                           "--rate",
                                           "0",
                                           "--json"};
  const ProcessResult streamed =
      Visloc(with(stream, {"--tls-cert", file("robot.pem"), "--tls-key", file("robot.key")}));
  ASSERT_EQ(streamed.exit_code, 0) << streamed.err;
  EXPECT_EQ(JsonNumber(streamed.out, "frames"), 5);
  EXPECT_EQ(JsonNumber(streamed.out, "errors"), 0);
  // Without a client certificate the robot never gets a stream, and says so.
  const ProcessResult refused = Visloc(stream);
  EXPECT_EQ(refused.exit_code, 1);
  EXPECT_THAT(refused.err, HasSubstr("gRPC code 14"));
}

}  // namespace
}  // namespace visloc
