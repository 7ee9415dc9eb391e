#include "mapstore/map_store.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <thread>

#include "core/map/synthetic_map.h"
#include "core/util/check.h"
#include "core/util/random.h"
#include "core/util/temp_dir.h"
#include "sqlite/sqlite.h"

namespace visloc::mapstore {
namespace {

using sqlite::Database;

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using ::testing::StartsWith;

Map SmallMap(uint64_t seed = 1) {
  SyntheticMapOptions options;
  options.keyframes = 12;
  options.points = 300;
  options.seed = seed;
  Map map = MakeSyntheticMap(options);
  map.metadata.name = "small";
  return map;
}

std::string LoadError(const std::string& path) {
  try {
    LoadMap(path);
  } catch (const InputError& e) {
    return e.what();
  }
  return "(loaded)";
}

// LoadError after meta's `key` in the map at `path` is set to `value`, or deleted when `value`
// is empty.
std::string LoadErrorWithMeta(const std::string& path, const std::string& key,
                              const std::string& value) {
  {
    Database db = Database::OpenForWriting(path);
    db.Exec(value.empty() ? "DELETE FROM meta WHERE key = '" + key + "'"
                          : "UPDATE meta SET value = '" + value + "' WHERE key = '" + key + "'");
  }
  return LoadError(path);
}

std::string ReadBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

void WriteBytes(const std::string& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
}

TEST(MapStoreTest, RoundTripIsExactAtRealisticSize) {
  TempDir dir;
  for (DescriptorType type : {DescriptorType::kFloat32, DescriptorType::kBinary}) {
    SyntheticMapOptions options;
    options.keyframes = 400;
    options.points = 40000;  // Several point chunks.
    options.descriptor_type = type;
    options.descriptor_dim = type == DescriptorType::kFloat32 ? 16 : 32;
    Map map = MakeSyntheticMap(options);
    map.metadata.name = "lab";
    const std::string path = dir.File("lab.db");
    SaveMap(map, path);
    EXPECT_TRUE(MapsEqual(LoadMap(path), map)) << ToString(type);
  }
  EXPECT_THAT(dir.FileNames(), ::testing::ElementsAre("lab.db"));  // no temporary left
}

TEST(MapStoreTest, SavingReplacesTheFileAndRefusesInconsistentMaps) {
  TempDir dir;
  const std::string path = dir.File("m.db");
  SaveMap(SmallMap(1), path);
  SaveMap(SmallMap(2), path);
  EXPECT_TRUE(MapsEqual(LoadMap(path), SmallMap(2)));
  Map broken = SmallMap(3);
  broken.points[4].observation_count = 77;
  EXPECT_THROW(SaveMap(broken, path), CheckError);
  EXPECT_TRUE(MapsEqual(LoadMap(path), SmallMap(2)));  // the old map is untouched
  EXPECT_THAT(dir.FileNames(), ::testing::ElementsAre("m.db"));
  EXPECT_THAT([&] { SaveMap(SmallMap(), dir.File("no/such/folder/m.db")); },
              ::testing::ThrowsMessage<InputError>(
                  HasSubstr("folder " + dir.File("no/such/folder") + " does not exist")));
}

TEST(MapStoreTest, SummaryAndVerifyOfASoundMap) {
  TempDir dir;
  const std::string path = dir.File("m.db");
  SaveMap(SmallMap(), path);
  const MapInfo info = SummarizeMap(LoadMap(path), path);
  EXPECT_EQ(info.keyframes, 12u);
  EXPECT_EQ(info.points, 300u);
  EXPECT_EQ(info.observations, 1200u);
  EXPECT_EQ(info.file_bytes, fs::file_size(path));
  EXPECT_TRUE(info.kernel_learned);
  EXPECT_EQ(info.vocabulary_words, 64u);
  EXPECT_FALSE(info.point_extent.isEmpty());
  EXPECT_TRUE(VerifyMapFile(path).ok());
}

// The rig's disparity correction is kept to the bit, covered by the checksum, and raises the
// schema only for maps that have one: a map without one is the schema-1 file it always was.
TEST(MapStoreTest, TheRigsDisparityCorrectionIsKeptExactlyAndOnlyWhereThereIsOne) {
  TempDir dir;
  const std::string plain = dir.File("plain.db"), rig = dir.File("rig.db");
  SaveMap(SmallMap(), plain);
  EXPECT_FALSE(LoadMap(plain).metadata.disparity_correction.has_value());
  EXPECT_EQ(SummarizeMap(LoadMap(plain), plain).schema_version, 1);
  Map map = SmallMap();
  map.metadata.disparity_correction = DisparityCorrection{-0.123456789012345, 0.001953125};
  SaveMap(map, rig);
  const Map loaded = LoadMap(rig);
  EXPECT_TRUE(MapsEqual(loaded, map));
  ASSERT_TRUE(loaded.metadata.disparity_correction.has_value());
  EXPECT_EQ(*loaded.metadata.disparity_correction, *map.metadata.disparity_correction);
  EXPECT_EQ(SummarizeMap(loaded, rig).schema_version, 3);
  EXPECT_TRUE(VerifyMapFile(rig).ok());

  EXPECT_EQ(LoadErrorWithMeta(rig, "disparity_offset_px", "0.5"),
            rig + ": content checksum mismatch: the file is corrupt or was modified");
  EXPECT_EQ(LoadErrorWithMeta(rig, "disparity_offset_px", "west"),
            rig + ": malformed disparity correction in meta ('west', '0.001953125')");
  EXPECT_EQ(LoadErrorWithMeta(rig, "right_camera_yaw_rad", ""),
            rig + ": meta has 'disparity_offset_px' without 'right_camera_yaw_rad'");
}

// The rig's calibration error likewise: kept to the bit, checksummed, schema 4 only where a
// builder was told one, and a file whose pair is broken or negative is refused by name.
TEST(MapStoreTest, TheRigsCalibrationErrorIsKeptExactlyAndOnlyWhereThereIsOne) {
  TempDir dir;
  const std::string plain = dir.File("plain.db"), exact = dir.File("exact.db");
  SaveMap(SmallMap(), plain);
  EXPECT_FALSE(LoadMap(plain).metadata.rig_error.has_value());
  Map map = SmallMap();
  map.metadata.rig_error = RigError{0.0, 0.0};
  SaveMap(map, exact);
  Map loaded = LoadMap(exact);
  EXPECT_TRUE(MapsEqual(loaded, map));
  ASSERT_TRUE(loaded.metadata.rig_error.has_value());
  EXPECT_EQ(*loaded.metadata.rig_error, RigError{});
  EXPECT_EQ(SummarizeMap(loaded, exact).schema_version, 4);
  map.metadata.rig_error = RigError{0.0023, 1.0 / 3.0};
  SaveMap(map, exact);
  loaded = LoadMap(exact);
  EXPECT_EQ(*loaded.metadata.rig_error, *map.metadata.rig_error);
  EXPECT_FALSE(MapsEqual(loaded, LoadMap(plain)));
  EXPECT_TRUE(VerifyMapFile(exact).ok());

  EXPECT_EQ(LoadErrorWithMeta(exact, "rig_error_floor_m", "0.001"),
            exact + ": content checksum mismatch: the file is corrupt or was modified");
  EXPECT_EQ(LoadErrorWithMeta(exact, "rig_error_floor_m", "-0.001"),
            exact + ": negative rig calibration error in meta (-0.001 m, 0.333333)");
  EXPECT_EQ(LoadErrorWithMeta(exact, "rig_error_drift_fraction", ""),
            exact + ": meta has 'rig_error_floor_m' without 'rig_error_drift_fraction'");
}

// The rig's stereo baseline likewise (schema 5): kept to the bit, checksummed, and refused by
// name when it is not a positive number.
TEST(MapStoreTest, TheRigsStereoBaselineIsKeptExactlyAndOnlyWhereThereIsOne) {
  TempDir dir;
  const std::string plain = dir.File("plain.db"), rig = dir.File("rig.db");
  SaveMap(SmallMap(), plain);
  EXPECT_FALSE(LoadMap(plain).metadata.stereo_baseline_m.has_value());
  Map map = SmallMap();
  map.metadata.stereo_baseline_m = 0.110077;
  SaveMap(map, rig);
  const Map loaded = LoadMap(rig);
  EXPECT_TRUE(MapsEqual(loaded, map));
  EXPECT_FALSE(MapsEqual(loaded, LoadMap(plain)));
  EXPECT_EQ(loaded.metadata.stereo_baseline_m, map.metadata.stereo_baseline_m);
  EXPECT_EQ(SummarizeMap(loaded, rig).schema_version, 5);
  EXPECT_TRUE(VerifyMapFile(rig).ok());

  EXPECT_EQ(LoadErrorWithMeta(rig, "stereo_baseline_m", "0.12"),
            rig + ": content checksum mismatch: the file is corrupt or was modified");
  EXPECT_EQ(LoadErrorWithMeta(rig, "stereo_baseline_m", "-0.11"),
            rig + ": malformed stereo baseline in meta ('-0.11'; a positive number of metres)");
  EXPECT_EQ(LoadErrorWithMeta(rig, "stereo_baseline_m", "wide"),
            rig + ": malformed stereo baseline in meta ('wide'; a positive number of metres)");
}

TEST(MapStoreTest, TheMapsUpDirectoryIsKeptExactlyWithHowItWasFound) {
  TempDir dir;
  const std::string path = dir.File("up.db");
  Map map = SmallMap();
  map.metadata.gravity = MapGravity{Eigen::Vector3d(0.0881, -0.936, -0.3407).normalized(), 0.37,
                                    MapGravity::Source::kFloor};
  SaveMap(map, path);
  const Map loaded = LoadMap(path);
  EXPECT_TRUE(MapsEqual(loaded, map));
  ASSERT_TRUE(loaded.metadata.gravity);
  EXPECT_EQ(*loaded.metadata.gravity, *map.metadata.gravity);  // Bit for bit.
  EXPECT_EQ(SummarizeMap(loaded, path).schema_version, 6);
  EXPECT_TRUE(VerifyMapFile(path).ok());
  map.metadata.gravity.reset();
  EXPECT_FALSE(MapsEqual(loaded, map));

  // Each damage named; a changed value the checksum catches.
  const auto damaged = [&](const std::string& key, const std::string& value) {
    SaveMap(loaded, path);
    return LoadErrorWithMeta(path, key, value);
  };
  EXPECT_EQ(damaged("gravity_sigma_deg", "0.5"),
            path + ": content checksum mismatch: the file is corrupt or was modified");
  const std::string source_error = damaged("gravity_source", "tea leaves");
  EXPECT_EQ(source_error.rfind(path + ": malformed up direction in meta ('", 0), 0u)
      << source_error;
  EXPECT_NE(source_error.find("', '0.37', 'tea leaves')"), std::string::npos) << source_error;
  EXPECT_NE(damaged("gravity_up", "0 2 0").find(": malformed up direction in meta ('0 2 0'"),
            std::string::npos);
  EXPECT_EQ(damaged("gravity_sigma_deg", ""),
            path +
                ": meta has part of the map's up direction ('gravity_up', "
                "'gravity_sigma_deg' and 'gravity_source' go together)");
}

TEST(MapStoreTest, TheSiteAlignmentIsKeptExactlyAndPartOfItIsRefused) {
  TempDir dir;
  const std::string path = dir.File("site.db");
  Map map = SmallMap();
  map.metadata.site = SiteAlignment{
      Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d(0.1, 0.2, 1).normalized())),
              Eigen::Vector3d(10.25, -2.5, 0.125)),
      5, 0.0081, 0.0153, "pairs spots, the hall.csv"};
  SaveMap(map, path);
  const Map loaded = LoadMap(path);
  EXPECT_TRUE(MapsEqual(loaded, map));
  EXPECT_EQ(SummarizeMap(loaded, path).schema_version, 7);
  EXPECT_TRUE(VerifyMapFile(path).ok());
  EXPECT_EQ(LoadErrorWithMeta(path, "site_rms_m", "0.009"),
            path + ": content checksum mismatch: the file is corrupt or was modified");
  SaveMap(loaded, path);
  EXPECT_NE(LoadErrorWithMeta(path, "site_pairs", "2").find(": malformed site alignment in meta"),
            std::string::npos);
  SaveMap(loaded, path);
  EXPECT_NE(LoadErrorWithMeta(path, "site_reference", "")
                .find(": meta has part of the map's site alignment"),
            std::string::npos);
}

// Each kind of bad file gets its own clear message.
class BadMapFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    path_ = dir_.File("m.db");
    SaveMap(SmallMap(), path_);
  }
  void Sql(const std::string& sql) {
    Database db = Database::OpenForWriting(path_);
    db.Exec(sql);
  }
  TempDir dir_;
  std::string path_;
};

TEST_F(BadMapFileTest, MissingEmptyAndForeignFiles) {
  EXPECT_EQ(LoadError(dir_.File("none.db")), dir_.File("none.db") + ": no such map file");
  WriteBytes(dir_.File("empty.db"), "");
  EXPECT_EQ(LoadError(dir_.File("empty.db")),
            dir_.File("empty.db") + ": empty file, not a visloc map");
  WriteBytes(dir_.File("text.db"), std::string(5000, 'x'));
  EXPECT_EQ(LoadError(dir_.File("text.db")), dir_.File("text.db") + ": not an SQLite database");
  {
    Database foreign = Database::OpenForWriting(dir_.File("foreign.db"));
    foreign.Exec("CREATE TABLE songs (title TEXT); INSERT INTO songs VALUES ('x');");
  }
  EXPECT_EQ(LoadError(dir_.File("foreign.db")),
            dir_.File("foreign.db") + ": not a visloc map (no 'meta' table)");
}

TEST_F(BadMapFileTest, TruncatedFile) {
  const std::string bytes = ReadBytes(path_);
  WriteBytes(path_, bytes.substr(0, bytes.size() / 2));
  EXPECT_THAT(LoadError(path_), StartsWith(path_ + ": "));
  EXPECT_NE(LoadError(path_), "(loaded)");
  EXPECT_FALSE(VerifyMapFile(path_).ok());
}

TEST_F(BadMapFileTest, MissingTableAndNewerSchema) {
  Sql("DROP TABLE vocabulary");
  EXPECT_EQ(LoadError(path_), path_ + ": missing table 'vocabulary'");
  Sql("UPDATE meta SET value = '8' WHERE key = 'schema_version'");
  EXPECT_EQ(
      LoadError(path_),
      path_ +
          ": written by a newer visloc (map schema 8; this visloc reads up to 7): upgrade visloc");
}

TEST_F(BadMapFileTest, DanglingObservation) {
  {
    Database db = Database::OpenForWriting(path_);
    const uint32_t points[2] = {5, 999999};
    const float pixels[4] = {1, 2, 3, 4};
    db.Prepare(
          "UPDATE keyframe_observations SET observation_count = 2, points = ?, pixels = ? WHERE "
          "keyframe_id = 11")
        .BindBlob(1, points, sizeof(points))
        .BindBlob(2, pixels, sizeof(pixels))
        .Run();
  }
  EXPECT_THAT(
      LoadError(path_),
      HasSubstr(
          "refers to keyframe 11 and point 999999 but the map has 12 keyframes and 300 points"));
}

TEST_F(BadMapFileTest, NonFinitePoseAndNonUnitQuaternion) {
  Sql("UPDATE keyframes SET tx = 1e999 WHERE id = 3");  // SQLite stores +inf
  EXPECT_EQ(LoadError(path_),
            path_ + ": keyframe 3 has a non-finite pose or a non-unit quaternion");
  SaveMap(SmallMap(), path_);
  Sql("UPDATE keyframes SET qw = 2 WHERE id = 5");
  EXPECT_EQ(LoadError(path_),
            path_ + ": keyframe 5 has a non-finite pose or a non-unit quaternion");
}

TEST_F(BadMapFileTest, ChangedValuesAndWrongBlobSizes) {
  Sql("UPDATE keyframes SET tx = tx + 0.001 WHERE id = 2");
  EXPECT_EQ(LoadError(path_),
            path_ + ": content checksum mismatch: the file is corrupt or was modified");
  SaveMap(SmallMap(), path_);
  Sql("UPDATE point_chunks SET positions = substr(positions, 1, 100)");
  EXPECT_EQ(LoadError(path_), path_ + ": point chunk 0 positions has 100 bytes, expected 7200");
  const VerifyReport report = VerifyMapFile(path_);
  ASSERT_EQ(report.problems.size(), 1u);
  EXPECT_EQ(report.problems[0], path_ + ": point chunk 0 positions has 100 bytes, expected 7200");
}

// Counts in the file decide allocations: a damaged count must be refused before it asks for
// gigabytes (found by the map fuzzer: a point count of ~2^30 made LoadMap allocate 10 GB).
TEST_F(BadMapFileTest, CountsTooLargeForTheFileAreRefusedBeforeAllocating) {
  const auto size = std::filesystem::file_size(path_);
  Sql("UPDATE point_chunks SET point_count = 1073741824 WHERE first_point = 0");
  // The small map's 300 points are one chunk, so the count read back is the damaged one.
  EXPECT_EQ(LoadError(path_),
            StrCat(path_, ": point count 1073741824 does not fit in a file of ", size, " bytes"));
}

// Damage at random places never crashes and never loads as a different map: the file is either
// rejected with an InputError or (damage in unused space) loads identical to the original.
TEST(MapStoreFuzzTest, RandomTruncationsAndByteFlips) {
  TempDir dir;
  const std::string good = dir.File("good.db"), bad = dir.File("bad.db");
  const Map original = SmallMap();
  SaveMap(original, good);
  const std::string bytes = ReadBytes(good);
  Rng rng(42);
  int rejected = 0, intact = 0;
  for (int trial = 0; trial < 160; ++trial) {
    std::string damaged = bytes;
    if (trial % 4 == 0) {
      damaged.resize(static_cast<size_t>(rng.Uniform(0, bytes.size() - 1)));
    } else {
      for (int flips = rng.UniformInt(1, 3); flips > 0; --flips) {
        damaged[static_cast<size_t>(rng.Uniform(0, bytes.size() - 1))] ^=
            static_cast<char>(1 << rng.UniformInt(0, 7));
      }
    }
    WriteBytes(bad, damaged);
    try {
      const Map loaded = LoadMap(bad);
      EXPECT_TRUE(MapsEqual(loaded, original)) << "trial " << trial << " loaded a different map";
      ++intact;
    } catch (const InputError& e) {
      EXPECT_THAT(e.what(), StartsWith(bad + ": ")) << "trial " << trial;
      EXPECT_FALSE(VerifyMapFile(bad).ok()) << "trial " << trial;
      ++rejected;
    }
  }
  EXPECT_GT(rejected, 40);
  RecordProperty("rejected", rejected);
  RecordProperty("intact", intact);
}

TEST(MapStoreConcurrencyTest, ReadersWhileAWriterReplacesTheMap) {
  TempDir dir;
  const std::string path = dir.File("m.db");
  const Map a = SmallMap(1), b = SmallMap(2);
  SaveMap(a, path);
  std::atomic<bool> stop{false};
  std::atomic<int> loads{0}, bad_loads{0};
  std::vector<std::thread> readers;
  for (int r = 0; r < 3; ++r) {
    readers.emplace_back([&] {
      while (!stop) {
        const Map loaded = LoadMap(path);
        if (!MapsEqual(loaded, a) && !MapsEqual(loaded, b)) ++bad_loads;
        ++loads;
      }
    });
  }
  for (int i = 0; i < 20; ++i) SaveMap(i % 2 ? a : b, path);
  stop = true;
  for (auto& reader : readers) reader.join();
  EXPECT_GT(loads.load(), 10);
  EXPECT_EQ(bad_loads.load(), 0);
}

}  // namespace
}  // namespace visloc::mapstore
