#include "mapstore/map_upload.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>

#include "core/map/synthetic_map.h"
#include "core/util/check.h"
#include "core/util/temp_dir.h"
#include "core/util/text_file.h"
#include "mapstore/checksum.h"

namespace visloc::mapstore {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

constexpr uint64_t kMaxBytes = 64 << 20;

// The bytes of a sound map file named NAME.
std::string MapFileBytes(const TempDir& scratch, const std::string& name, int points) {
  SyntheticMapOptions options;
  options.keyframes = 6;
  options.points = points;
  Map map = MakeSyntheticMap(options);
  map.metadata.name = name;
  const std::string path = scratch.File(name + "_source.db");
  SaveMap(map, path);
  return ReadFileBytes(path);
}

class MapUploadTest : public ::testing::Test {
 protected:
  TempDir scratch_{"visloc_map_upload_scratch"};
  TempDir maps_dir_{"visloc_map_upload_maps"};
  MapDirectory maps_{maps_dir_.path()};
};

TEST_F(MapUploadTest, AWholeUploadInPiecesIsPublishedUnderItsName) {
  const std::string bytes = MapFileBytes(scratch_, "lab", 200);
  MapUpload upload(maps_, "lab", bytes.size(), Crc32(bytes), kMaxBytes);
  for (size_t at = 0; at < bytes.size(); at += 4096) upload.Append(bytes.substr(at, 4096));
  const MapDirectory::Entry entry = upload.Publish(/*replace=*/false);
  EXPECT_EQ(entry.name, "lab");
  ASSERT_TRUE(entry.info.has_value()) << entry.error;
  EXPECT_EQ(entry.info->points, 200u);
  EXPECT_EQ(maps_dir_.FileNames(), std::vector<std::string>{"lab.db"});
}

TEST_F(MapUploadTest, CutOffWrongOrOversizedUploadsLeaveNothingAndTheOldMapStands) {
  const std::string old_map = MapFileBytes(scratch_, "lab", 150);
  {
    MapUpload first(maps_, "lab", old_map.size(), Crc32(old_map), kMaxBytes);
    first.Append(old_map);
    first.Publish(false);
  }
  const std::string bytes = MapFileBytes(scratch_, "lab", 300);
  {
    MapUpload cut(maps_, "lab", bytes.size(), Crc32(bytes), kMaxBytes);
    cut.Append(bytes.substr(0, bytes.size() / 2));
    try {
      cut.Publish(true);
      FAIL() << "a cut-off upload was published";
    } catch (const InputError& e) {
      EXPECT_THAT(e.what(), HasSubstr("upload cut off"));
    }
  }
  {
    MapUpload wrong(maps_, "lab", bytes.size(), Crc32(bytes) ^ 1u, kMaxBytes);
    wrong.Append(bytes);
    try {
      wrong.Publish(true);
      FAIL() << "an upload with the wrong checksum was published";
    } catch (const InputError& e) {
      EXPECT_THAT(e.what(), HasSubstr("checksum mismatch"));
    }
  }
  {
    MapUpload longer(maps_, "lab", 10, 0, kMaxBytes);
    EXPECT_THROW(longer.Append(bytes), InputError);
  }
  {
    MapUpload abandoned(maps_, "lab", bytes.size(), Crc32(bytes), kMaxBytes);
    abandoned.Append(bytes.substr(0, 100));
  }
  EXPECT_THROW(MapUpload(maps_, "lab", bytes.size(), 0, bytes.size() - 1), InputError);
  EXPECT_THROW(MapUpload(maps_, "../lab", bytes.size(), 0, kMaxBytes), InputError);
  EXPECT_EQ(maps_dir_.FileNames(), std::vector<std::string>{"lab.db"});
  EXPECT_EQ(maps_.Describe("lab").info->points, 150u);
}

TEST_F(MapUploadTest, AFileThatIsNotAMapIsRefusedAtPublish) {
  const std::string bytes = "these bytes are not a map file at all";
  MapUpload upload(maps_, "junk", bytes.size(), Crc32(bytes), kMaxBytes);
  upload.Append(bytes);
  EXPECT_THROW(upload.Publish(false), InputError);
  EXPECT_TRUE(maps_dir_.FileNames().empty());
}

}  // namespace
}  // namespace visloc::mapstore
