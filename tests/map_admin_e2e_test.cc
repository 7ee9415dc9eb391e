// Map management through the real server: `visloc map upload|list|info|download|rename|delete
// --server` against visloc-server on loopback, plus a raw gRPC client for what the CLI never
// does (an upload cut off half-way, a wrong checksum, a file that is not a map).

#include <gmock/gmock.h>
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>

#include "core/map/synthetic_map.h"
#include "core/util/temp_dir.h"
#include "core/util/text_file.h"
#include "mapstore/checksum.h"
#include "mapstore/map_store.h"
#include "tests/support/e2e.h"
#include "tests/support/process.h"
#include "tests/support/upload.h"
#include "visloc/v1/visloc.grpc.pb.h"

namespace visloc {
namespace {

using ::testing::HasSubstr;
using testing::JsonNumber;
using ::testing::Not;
using testing::ProcessResult;
using testing::ServerProcess;
using testing::Visloc;

size_t FilesIn(const std::string& dir) {
  size_t n = 0;
  for ([[maybe_unused]] const auto& file : std::filesystem::directory_iterator(dir)) ++n;
  return n;
}

class MapAdminE2eTest : public ::testing::Test {
 protected:
  void SetUp() override { testing::SaveLabMap(local_.File("lab.db")); }
  // Sends a header and then `bytes`, optionally cancelling after `cut_after` bytes.
  grpc::Status RawUpload(const std::string& name, const std::string& bytes, uint32_t crc,
                         size_t cut_after = std::string::npos) {
    auto stub = v1::MapAdmin::NewStub(
        grpc::CreateChannel(server_.address(), grpc::InsecureChannelCredentials()));
    grpc::ClientContext context;
    v1::MapInfo info;
    auto writer = stub->UploadMap(&context, &info);
    testing::SendUpload(writer.get(), name, bytes, crc, cut_after);
    if (cut_after != std::string::npos) {
      context.TryCancel();  // The client vanishes mid-upload.
    } else {
      writer->WritesDone();
    }
    return writer->Finish();
  }
  static uint32_t Crc(const std::string& bytes) { return mapstore::Crc32(bytes); }

  TempDir local_{"visloc_admin_local"};
  TempDir maps_{"visloc_admin_maps"};
  ServerProcess server_{VISLOC_SERVER_PATH, maps_.path()};
};

TEST_F(MapAdminE2eTest, UploadListDownloadRenameDelete) {
  const std::string address = server_.address();
  const ProcessResult upload =
      Visloc({"map", "upload", local_.File("lab.db"), "--server", address});
  ASSERT_EQ(upload.exit_code, 0) << upload.err;
  EXPECT_THAT(upload.out, HasSubstr("uploaded"));
  EXPECT_TRUE(std::filesystem::exists(maps_.File("lab.db")));

  const ProcessResult list = Visloc({"map", "list", "--server", address, "--json"});
  ASSERT_EQ(list.exit_code, 0) << list.err;
  EXPECT_THAT(list.out, HasSubstr("\"name\":\"lab\""));
  EXPECT_THAT(list.out, HasSubstr("\"points\":2000"));

  const ProcessResult again = Visloc({"map", "upload", local_.File("lab.db"), "--server", address});
  EXPECT_EQ(again.exit_code, 1);
  EXPECT_THAT(again.err, HasSubstr("already exists; replace it with visloc map upload --replace"));
  EXPECT_EQ(
      Visloc({"map", "upload", local_.File("lab.db"), "--server", address, "--replace"}).exit_code,
      0);

  const std::string copy = local_.File("copy.db");
  const ProcessResult download =
      Visloc({"map", "download", "lab", "--out", copy, "--server", address});
  ASSERT_EQ(download.exit_code, 0) << download.err;
  EXPECT_EQ(ReadFileBytes(copy), ReadFileBytes(local_.File("lab.db")));

  const ProcessResult info = Visloc({"map", "info", "lab", "--server", address, "--json"});
  ASSERT_EQ(info.exit_code, 0) << info.err;
  EXPECT_THAT(info.out, HasSubstr("\"keyframes\":20"));

  ASSERT_EQ(Visloc({"map", "rename", "lab", "lab2", "--server", address}).exit_code, 0);
  EXPECT_THAT(Visloc({"map", "list", "--server", address}).out, HasSubstr("lab2"));
  ASSERT_EQ(Visloc({"map", "delete", "lab2", "--server", address}).exit_code, 0);
  EXPECT_EQ(FilesIn(maps_.path()), 0u);
  const ProcessResult missing_info = Visloc({"map", "info", "lab2", "--server", address});
  EXPECT_EQ(missing_info.exit_code, 1);
  EXPECT_THAT(missing_info.err, HasSubstr("no map named 'lab2' (gRPC code 5)"));  // NOT_FOUND
  const ProcessResult gone = Visloc({"map", "delete", "lab2", "--server", address});
  EXPECT_EQ(gone.exit_code, 1);
  EXPECT_THAT(gone.err, HasSubstr("no map named 'lab2'"));
}

// With --json every map verb prints one JSON object on stdout, whether it worked ("ok":true and
// what it did) or not ("ok":false, the error and the exit code), remote and local alike.
TEST_F(MapAdminE2eTest, EveryMapVerbAnswersInJsonWhenAsked) {
  const std::string address = server_.address();
  const auto json = [](std::vector<std::string> argv, int exit_code) {
    argv.push_back("--json");
    const ProcessResult run = Visloc(argv);
    EXPECT_EQ(run.exit_code, exit_code) << run.err;
    EXPECT_EQ(run.out.front(), '{') << run.out;
    EXPECT_EQ(run.out.substr(run.out.size() - 2), "}\n") << run.out;
    EXPECT_EQ(std::count(run.out.begin(), run.out.end(), '\n'), 1) << run.out;
    return run.out;
  };
  EXPECT_THAT(json({"map", "upload", local_.File("lab.db"), "--server", address}, 0),
              HasSubstr("\"ok\":true,\"map\":\"lab\""));
  EXPECT_THAT(json({"map", "upload", local_.File("lab.db"), "--server", address}, 1),
              HasSubstr("\"ok\":false,\"command\":\"visloc map upload\",\"error\":\"server "));
  EXPECT_THAT(json({"map", "download", "lab", "--out", local_.File("copy.db"), "--server",
                    address}, 0),
              HasSubstr("\"bytes\":"));
  EXPECT_THAT(json({"map", "rename", "lab", "lab2", "--server", address}, 0),
              HasSubstr("\"renamed\":\"lab\",\"to\":\"lab2\""));
  EXPECT_THAT(json({"map", "delete", "lab2", "--server", address}, 0),
              HasSubstr("\"deleted\":\"lab2\""));
  EXPECT_THAT(json({"map", "info", "lab2", "--server", address}, 1),
              HasSubstr("no map named 'lab2'"));
  EXPECT_THAT(json({"map", "export", local_.File("copy.db"), "--keyframes",
                    local_.File("k.tum")}, 0),
              HasSubstr("\"keyframes\":20"));
  EXPECT_THAT(json({"plot", "--map", local_.File("copy.db"), "--trajectory", local_.File("k.tum"),
                    "--out", local_.File("top.png")}, 0),
              HasSubstr("\"keyframes\":20"));
  EXPECT_THAT(json({"map", "info", local_.File("nope.db")}, 1),
              HasSubstr("\"error\":\"" + local_.File("nope.db") + ": no such map file\""));
  EXPECT_THAT(json({"map", "rename", "copy", "lab3", "--maps", local_.path()}, 0),
              HasSubstr("\"to\":\"lab3\""));
  EXPECT_THAT(json({"map", "delete", "lab3", "--maps", local_.path()}, 0),
              HasSubstr("\"deleted\":\"lab3\""));
  EXPECT_THAT(json({"map", "build"}, 2), HasSubstr("\"exit_code\":2"));
  EXPECT_THAT(json({"health", "--server", "127.0.0.1:1", "--timeout-s", "1"}, 1),
              HasSubstr("\"command\":\"visloc health\""));
}

// A map on the server reads as the same file does locally: `map info` shows the camera, extent,
// features and the rest line for line, `map list` has the same columns, and a broken map on
// the server fails `map info` (exit 1) as a broken local file does.
TEST_F(MapAdminE2eTest, RemoteInfoAndListReadAsTheLocalFile) {
  const std::string address = server_.address();
  ASSERT_EQ(Visloc({"map", "upload", local_.File("lab.db"), "--server", address}).exit_code, 0);
  const ProcessResult local = Visloc({"map", "info", local_.File("lab.db")});
  const ProcessResult remote = Visloc({"map", "info", "lab", "--server", address});
  ASSERT_EQ(local.exit_code, 0) << local.err;
  ASSERT_EQ(remote.exit_code, 0) << remote.err;
  // All but the first line (which names where the map is) are the same.
  const auto after_first_line = [](const std::string& text) {
    return text.substr(text.find('\n') + 1);
  };
  EXPECT_EQ(after_first_line(remote.out), after_first_line(local.out));
  EXPECT_THAT(remote.out, HasSubstr("camera        "));
  EXPECT_THAT(remote.out, HasSubstr("lab on " + address));
  const ProcessResult local_json = Visloc({"map", "info", local_.File("lab.db"), "--json"});
  const ProcessResult remote_json = Visloc({"map", "info", "lab", "--server", address, "--json"});
  const auto without_path = [](const std::string& json) {
    const size_t start = json.find("\"path\":");
    return json.substr(0, start) + json.substr(json.find(',', start) + 1);
  };
  EXPECT_EQ(without_path(remote_json.out), without_path(local_json.out));

  std::filesystem::copy_file(local_.File("lab.db"), local_.File("folder_lab.db"));
  const ProcessResult local_list = Visloc({"map", "list", "--maps", maps_.path()});
  const ProcessResult remote_list = Visloc({"map", "list", "--server", address});
  const auto first_two_lines = [](const std::string& text) {
    return text.substr(0, text.find('\n', text.find('\n') + 1));
  };
  EXPECT_EQ(first_two_lines(remote_list.out), first_two_lines(local_list.out));
  EXPECT_THAT(remote_list.out, HasSubstr("1 maps on " + address));

  const std::string bytes = ReadFileBytes(local_.File("lab.db"));
  std::ofstream(maps_.File("broken.db"), std::ios::binary) << bytes.substr(0, bytes.size() / 2);
  const ProcessResult broken = Visloc({"map", "info", "broken", "--server", address});
  EXPECT_EQ(broken.exit_code, 1);
  EXPECT_THAT(broken.err, HasSubstr("broken on " + address + ": unavailable: "));
  EXPECT_THAT(Visloc({"map", "list", "--server", address}).out,
              HasSubstr("broken                   unavailable: "));
}

TEST_F(MapAdminE2eTest, AnUploadCutOffHalfWayLeavesNoMapBehind) {
  const std::string bytes = ReadFileBytes(local_.File("lab.db"));
  const grpc::Status status = RawUpload("lab", bytes, Crc(bytes), bytes.size() / 2);
  EXPECT_FALSE(status.ok());
  // The server notices the cancellation and removes the staged half.
  EXPECT_TRUE(testing::WaitUntil([&] { return FilesIn(maps_.path()) == 0; }))
      << FilesIn(maps_.path()) << " files left";
  EXPECT_THAT(Visloc({"map", "list", "--server", server_.address()}).out, HasSubstr("0 maps"));
  // And the server still takes a complete upload.
  EXPECT_TRUE(RawUpload("lab", bytes, Crc(bytes)).ok());
  EXPECT_TRUE(std::filesystem::exists(maps_.File("lab.db")));
}

TEST_F(MapAdminE2eTest, WrongChecksumsForeignFilesAndEscapingNamesAreRefused) {
  const std::string bytes = ReadFileBytes(local_.File("lab.db"));
  grpc::Status status = RawUpload("lab", bytes, Crc(bytes) ^ 1u);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(status.error_message(), HasSubstr("checksum mismatch"));
  const std::string not_a_map(4096, 'x');
  status = RawUpload("junk", not_a_map, Crc(not_a_map));
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(status.error_message(), HasSubstr("not sound"));
  // The server's insides stay on the server: no maps folder, no staging file name.
  EXPECT_THAT(status.error_message(), HasSubstr("map 'junk' (staged upload)"));
  EXPECT_THAT(status.error_message(), Not(HasSubstr(maps_.path())));
  EXPECT_THAT(status.error_message(), Not(HasSubstr(".tmp-")));
  status = RawUpload("../escape", bytes, Crc(bytes));
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(status.error_message(), HasSubstr("invalid map name '../escape'"));
  EXPECT_EQ(FilesIn(maps_.path()), 0u);
  EXPECT_FALSE(std::filesystem::exists(maps_.File("../escape.db")));
}

}  // namespace
}  // namespace visloc
