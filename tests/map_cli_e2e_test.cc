// End-to-end tests of `visloc map ...` on real map files written by a real writer process.

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "core/util/temp_dir.h"
#include "dataset/ply.h"
#include "dataset/tum.h"
#include "sqlite/sqlite.h"
#include "tests/support/e2e.h"
#include "tests/support/process.h"

namespace visloc {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using testing::JsonNumber;
using testing::ProcessResult;
using testing::Visloc;

void WriteMap(const std::string& path, int points, int seed) {
  ASSERT_EQ(
      testing::RunProcess({VISLOC_WRITER_PATH, path, std::to_string(points), std::to_string(seed)})
          .exit_code,
      0);
}

class MapCliTest : public ::testing::Test {
 protected:
  void SetUp() override {
    WriteMap(dir_.File("lab.db"), 2000, 1);
    WriteMap(dir_.File("hall.db"), 500, 2);
  }
  TempDir dir_;
};

TEST_F(MapCliTest, InfoByPathAndByName) {
  const ProcessResult by_path = Visloc({"map", "info", dir_.File("lab.db"), "--json"});
  ASSERT_EQ(by_path.exit_code, 0) << by_path.err;
  EXPECT_THAT(by_path.out, HasSubstr("\"keyframes\":20,\"points\":2000,\"observations\":8000"));
  EXPECT_THAT(by_path.out, HasSubstr("\"schema_version\":1"));
  const ProcessResult by_name = Visloc({"map", "info", "hall", "--maps", dir_.path()});
  ASSERT_EQ(by_name.exit_code, 0) << by_name.err;
  EXPECT_THAT(by_name.out, HasSubstr("points        500,"));
  EXPECT_THAT(by_name.out, HasSubstr("features      harris_surf16 (float32 x 16)"));
}

TEST_F(MapCliTest, VerifyPassesSoundMapsAndNamesTheProblemOtherwise) {
  const ProcessResult ok = Visloc({"map", "verify", dir_.File("lab.db")});
  EXPECT_EQ(ok.exit_code, 0);
  EXPECT_EQ(ok.out, dir_.File("lab.db") + ": ok\n");
  {
    sqlite::Database db = sqlite::Database::OpenForWriting(dir_.File("hall.db"));
    db.Exec("UPDATE keyframes SET qw = 3 WHERE id = 2");
  }
  const ProcessResult bad = Visloc({"map", "verify", dir_.File("hall.db")});
  EXPECT_EQ(bad.exit_code, 1);
  EXPECT_EQ(bad.err, "visloc map verify: " + dir_.File("hall.db") +
                         ": keyframe 2 has a non-finite pose or a non-unit quaternion\n");
}

TEST_F(MapCliTest, BadFilesGetOneLineErrors) {
  std::ofstream(dir_.File("empty.db"));
  std::ofstream(dir_.File("text.db")) << std::string(3000, 'z');
  {
    sqlite::Database db = sqlite::Database::OpenForWriting(dir_.File("foreign.db"));
    db.Exec("CREATE TABLE t (x INTEGER)");
  }
  const std::string lab = dir_.File("lab.db");
  std::ifstream in(lab, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), {});
  std::ofstream(dir_.File("cut.db"), std::ios::binary) << bytes.substr(0, bytes.size() / 3);
  const std::pair<std::string, std::string> cases[] = {
      {"empty.db", "empty file, not a visloc map"},
      {"text.db", "not an SQLite database"},
      {"foreign.db", "not a visloc map (no 'meta' table)"},
      {"missing.db", "no such map file"},
      {"cut.db", ""},
  };
  for (const auto& [file, message] : cases) {
    const ProcessResult result = Visloc({"map", "info", dir_.File(file)});
    EXPECT_EQ(result.exit_code, 1) << file;
    EXPECT_EQ(std::count(result.err.begin(), result.err.end(), '\n'), 1) << result.err;
    EXPECT_THAT(result.err, HasSubstr("visloc map info: " + dir_.File(file) + ": " + message))
        << file;
  }
}

TEST_F(MapCliTest, ExportWritesKeyframesAndACloud) {
  const ProcessResult result = Visloc({"map", "export", dir_.File("lab.db"), "--keyframes",
                                       dir_.File("kf.tum"), "--ply", dir_.File("lab.ply")});
  ASSERT_EQ(result.exit_code, 0) << result.err;
  EXPECT_EQ(ReadTum(dir_.File("kf.tum")).size(), 20u);
  const auto cloud = ReadPly(dir_.File("lab.ply"));
  ASSERT_EQ(cloud.size(), 2020u);
  EXPECT_EQ(cloud.back().rgb, (std::array<uint8_t, 3>{255, 0, 0}));
  EXPECT_EQ(Visloc({"map", "export", dir_.File("lab.db")}).exit_code, 2);
}

TEST_F(MapCliTest, ListDeleteAndRenameInAMapsFolder) {
  std::ofstream(dir_.File("broken.db")) << "garbage";
  const ProcessResult list = Visloc({"map", "list", "--maps", dir_.path()});
  ASSERT_EQ(list.exit_code, 0) << list.err;
  EXPECT_THAT(list.out, HasSubstr("broken                   unavailable: "));
  EXPECT_THAT(list.out, HasSubstr("3 maps in"));
  EXPECT_EQ(Visloc({"map", "rename", "lab", "lab-v2", "--maps", dir_.path()}).exit_code, 0);
  EXPECT_THAT(Visloc({"map", "info", "lab-v2", "--maps", dir_.path()}).out,
              HasSubstr("map           lab-v2 "));
  const ProcessResult traversal =
      Visloc({"map", "rename", "hall", "../escape", "--maps", dir_.path()});
  EXPECT_EQ(traversal.exit_code, 1);
  EXPECT_THAT(traversal.err, HasSubstr("invalid map name '../escape'"));
  EXPECT_EQ(Visloc({"map", "delete", "hall", "--maps", dir_.path()}).exit_code, 0);
  const ProcessResult again = Visloc({"map", "delete", "hall", "--maps", dir_.path()});
  EXPECT_EQ(again.exit_code, 1);
  EXPECT_THAT(again.err, HasSubstr("no map named 'hall'"));
  EXPECT_FALSE(fs::exists(dir_.File("hall.db")));
  EXPECT_FALSE(fs::exists(dir_.path() + "/../escape.db"));
}

}  // namespace
}  // namespace visloc
