// OpenPagedMap: a map file served in pages gives what LoadMap gives, and refuses what it refuses.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "core/map/localization_map.h"
#include "core/map/synthetic_map.h"
#include "core/util/check.h"
#include "core/util/temp_dir.h"
#include "mapstore/map_store.h"
#include "sqlite/sqlite.h"

namespace visloc::mapstore {
namespace {

using sqlite::Database;

using ::testing::HasSubstr;

// Twenty point chunks (1024 points each, the last partial).
Map TwentyChunkMap(uint64_t seed = 1) {
  SyntheticMapOptions options;
  options.keyframes = 40;
  options.points = 20000;
  options.seed = seed;
  Map map = MakeSyntheticMap(options);
  map.metadata.name = "big";
  return map;
}

std::string OpenError(const std::string& path) {
  try {
    OpenPagedMap(path);
  } catch (const InputError& e) {
    return e.what();
  }
  return "(opened)";
}

void ExpectSamePoints(const LocalizationMap& resident, const LocalizationMap& paged) {
  ASSERT_EQ(paged.point_count(), resident.point_count());
  for (size_t k = 0; k < resident.keyframe_count(); ++k) {
    const auto a = resident.VisiblePoints(k), b = paged.VisiblePoints(k);
    const std::vector<uint32_t> ids(b.begin(), b.end());
    ASSERT_EQ(std::vector<uint32_t>(a.begin(), a.end()), ids) << "keyframe " << k;
    const PointView from_file = paged.Points(ids), from_memory = resident.Points(ids);
    for (uint32_t id : ids) {
      ASSERT_EQ(from_file.position(id), from_memory.position(id)) << id;
      int row_a = 0, row_b = 0;
      const cv::Mat& da = from_memory.descriptors(id, &row_a);
      const cv::Mat& db = from_file.descriptors(id, &row_b);
      ASSERT_EQ(cv::norm(da.row(row_a), db.row(row_b), cv::NORM_L1), 0.0) << id;
    }
  }
}

TEST(PagedMapFileTest, ServesWhatLoadMapLoadsWithinItsBudget) {
  TempDir dir;
  const std::string path = dir.File("big.db");
  SaveMap(TwentyChunkMap(), path);
  const LocalizationMap resident(LoadMap(path));
  PagedMap opened = OpenPagedMap(path);
  EXPECT_TRUE(opened.skeleton.points.empty());
  EXPECT_EQ(opened.skeleton.keyframes.size(), 40u);
  EXPECT_EQ(opened.pages->chunk_points(), 1024u);
  // Room for a few chunks and visibility lists: pages are evicted and read again.
  const size_t budget = 600 * 1024;
  const LocalizationMap paged(std::move(opened.skeleton), opened.pages, budget);
  ExpectSamePoints(resident, paged);
  const PageCacheStats stats = paged.page_stats();
  EXPECT_GT(stats.evictions, 0u);
  EXPECT_LE(stats.peak_cached_bytes, budget);
}

TEST(PagedMapFileTest, KeepsServingTheFileItOpenedWhenTheMapIsReplaced) {
  TempDir dir;
  const std::string path = dir.File("big.db");
  SaveMap(TwentyChunkMap(1), path);
  const LocalizationMap before(LoadMap(path));
  PagedMap opened = OpenPagedMap(path);
  const LocalizationMap paged(std::move(opened.skeleton), opened.pages, 64 * 1024);
  SaveMap(TwentyChunkMap(2), path);  // Replaced by rename, as every save and upload does.
  ExpectSamePoints(before, paged);
}

class BadPagedFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    path_ = dir_.File("m.db");
    SaveMap(TwentyChunkMap(), path_);
  }
  void Sql(const std::string& sql) {
    Database db = Database::OpenForWriting(path_);
    db.Exec(sql);
  }
  TempDir dir_;
  std::string path_;
};

TEST_F(BadPagedFileTest, AChangedPointOrDescriptorOrObservationFailsTheChecksum) {
  const std::string mismatch =
      path_ + ": content checksum mismatch: the file is corrupt or was modified";
  // One byte of the second chunk's positions, descriptors, then one observation pixel.
  Sql("UPDATE point_chunks SET positions = substr(positions, 1, 99) || x'7f' || substr(positions, "
      "101) WHERE id = 1");
  EXPECT_EQ(OpenError(path_), mismatch);
  SaveMap(TwentyChunkMap(), path_);
  Sql("UPDATE point_chunks SET descriptors = x'00000000' || substr(descriptors, 5) WHERE id = 2");
  EXPECT_EQ(OpenError(path_), mismatch);
  SaveMap(TwentyChunkMap(), path_);
  Sql("UPDATE keyframe_observations SET pixels = x'0000c842' || substr(pixels, 5) WHERE "
      "keyframe_id = 7");
  EXPECT_EQ(OpenError(path_), mismatch);
}

TEST_F(BadPagedFileTest, DanglingObservationsAndShortBlobsAreNamed) {
  {
    Database db = Database::OpenForWriting(path_);
    const uint32_t points[1] = {999999};
    const float pixels[2] = {1, 2};
    db.Prepare(
          "UPDATE keyframe_observations SET observation_count = 1, points = ?, pixels = ? "
          "WHERE keyframe_id = 11")
        .BindBlob(1, points, sizeof(points))
        .BindBlob(2, pixels, sizeof(pixels))
        .Run();
  }
  EXPECT_EQ(OpenError(path_), path_ +
                                  ": observation 0 of keyframe 11 refers to point 999999 but "
                                  "the map has 20000 points");
  SaveMap(TwentyChunkMap(), path_);
  Sql("UPDATE point_chunks SET positions = substr(positions, 1, 100) WHERE id = 0");
  EXPECT_EQ(OpenError(path_), path_ + ": point chunk 0 positions has 100 bytes, expected 24576");
  EXPECT_EQ(OpenError(dir_.File("none.db")), dir_.File("none.db") + ": no such map file");
}

}  // namespace
}  // namespace visloc::mapstore
