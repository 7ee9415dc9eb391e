#include "mapstore/map_directory.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "core/map/synthetic_map.h"
#include "core/util/check.h"
#include "core/util/temp_dir.h"

namespace visloc::mapstore {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

Map NamedMap(const std::string& name) {
  SyntheticMapOptions options;
  options.keyframes = 8;
  options.points = 100;
  Map map = MakeSyntheticMap(options);
  map.metadata.name = name;
  return map;
}

TEST(MapNameTest, RejectsNamesThatEscapeOrHide) {
  for (const char* good : {"lab", "lab-2", "floor_3.v2", "A"})
    EXPECT_TRUE(IsValidMapName(good)) << good;
  for (const char* bad :
       {"", "../lab", "/etc/passwd", "a/b", ".hidden", "-rf", "lab map", "x\n", "a\\b"}) {
    EXPECT_FALSE(IsValidMapName(bad)) << bad;
  }
  EXPECT_FALSE(IsValidMapName(std::string(65, 'a')));
  EXPECT_THAT([] { CheckMapName("../lab"); },
              ::testing::ThrowsMessage<InputError>(HasSubstr("invalid map name '../lab'")));
}

TEST(MapDirectoryTest, ListsMapsWithBrokenOnesExplained) {
  TempDir dir;
  MapDirectory maps(dir.path());
  SaveMap(NamedMap("lab"), maps.PathOf("lab"));
  SaveMap(NamedMap("hall"), maps.PathOf("hall"));
  std::ofstream(dir.File("broken.db")) << "not a map";
  std::ofstream(dir.File("notes.txt")) << "ignored";
  const auto entries = maps.List();
  ASSERT_EQ(entries.size(), 3u);
  EXPECT_EQ(entries[0].name, "broken");
  EXPECT_FALSE(entries[0].info);
  EXPECT_THAT(entries[0].error, HasSubstr("not an SQLite database"));
  EXPECT_EQ(entries[1].name, "hall");
  ASSERT_TRUE(entries[1].info);
  EXPECT_EQ(entries[1].info->points, 100u);
  EXPECT_EQ(entries[2].name, "lab");
}

TEST(MapDirectoryTest, RemoveAndRename) {
  TempDir dir;
  MapDirectory maps(dir.path());
  SaveMap(NamedMap("lab"), maps.PathOf("lab"));
  SaveMap(NamedMap("hall"), maps.PathOf("hall"));
  maps.Rename("lab", "lab2");
  EXPECT_FALSE(maps.Contains("lab"));
  EXPECT_EQ(LoadMap(maps.PathOf("lab2")).metadata.name, "lab2");
  EXPECT_THAT([&] { maps.Rename("lab2", "hall"); },
              ::testing::ThrowsMessage<InputError>(HasSubstr("a map named 'hall' already exists")));
  EXPECT_THAT([&] { maps.Rename("nope", "x"); },
              ::testing::ThrowsMessage<InputError>(HasSubstr("no map named 'nope'")));
  EXPECT_THAT([&] { maps.Rename("hall", "../x"); },
              ::testing::ThrowsMessage<InputError>(HasSubstr("invalid map name '../x'")));
  maps.Remove("hall");
  EXPECT_FALSE(maps.Contains("hall"));
  EXPECT_THAT([&] { maps.Remove("hall"); },
              ::testing::ThrowsMessage<InputError>(HasSubstr("no map named 'hall'")));
  EXPECT_THAT([] { MapDirectory("/nonexistent/maps"); },
              ::testing::ThrowsMessage<InputError>(HasSubstr("no such maps folder")));
}

TEST(MapDirectoryTest, DescribesOneMapAndSaysWhenThereIsNone) {
  TempDir dir;
  MapDirectory maps(dir.path());
  SaveMap(NamedMap("lab"), maps.PathOf("lab"));
  { std::ofstream(maps.PathOf("broken")) << "not a map"; }
  const MapDirectory::Entry lab = maps.Describe("lab");
  EXPECT_EQ(lab.name, "lab");
  ASSERT_TRUE(lab.info.has_value());
  EXPECT_EQ(lab.info->metadata.name, "lab");
  EXPECT_GT(lab.file_bytes, 0u);
  const MapDirectory::Entry broken = maps.Describe("broken");
  EXPECT_FALSE(broken.info.has_value());
  EXPECT_FALSE(broken.error.empty());
  // A missing map is a NotFoundError (services answer "not found"), a bad name only InputError.
  EXPECT_THAT([&] { maps.Describe("nope"); },
              ::testing::ThrowsMessage<NotFoundError>(HasSubstr("no map named 'nope'")));
  EXPECT_THROW(maps.Remove("nope"), NotFoundError);
  EXPECT_THROW(maps.Rename("nope", "x"), NotFoundError);
  try {
    maps.Describe("../etc");
    FAIL() << "expected InputError";
  } catch (const NotFoundError&) {
    FAIL() << "an invalid name is not 'not found'";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("invalid map name"));
  }
}

TEST(MapDirectoryTest, RemovesTemporariesOfDeadWritersOnly) {
  TempDir dir;
  MapDirectory maps(dir.path());
  std::ofstream(dir.File(".lab.db.tmp-999999999-0")) << "partial";  // no such process
  const std::string live = dir.File(".lab.db.tmp-" + std::to_string(getpid()) + "-0");
  std::ofstream(live) << "being written";
  EXPECT_EQ(maps.RemoveStaleTemporaries(), 1);
  EXPECT_TRUE(fs::exists(live));
  EXPECT_TRUE(maps.List().empty());
}

}  // namespace
}  // namespace visloc::mapstore
