#pragma once
// The map file's internals, shared by the files of mapstore that write it (map_write.cc), read it
// whole (map_read.cc) or page it (paged_map.cc): the schema, the content checksum, BLOB packing
// and the readers of each table. Nothing outside mapstore/ includes this; the format is
// docs/map_format.md.

#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>
#include <vector>

#include "core/map/map.h"
#include "core/map/map_pages.h"
#include "core/util/check.h"
#include "core/util/strings.h"
#include "mapstore/checksum.h"
#include "sqlite/sqlite.h"

namespace visloc::mapstore::internal {

using sqlite::Database;
using sqlite::Statement;
using sqlite::Transaction;

static_assert(sizeof(float) == 4 && sizeof(double) == 8, "IEEE floats expected");

// Schema version 1. Bulk data is packed into BLOBs: points in chunks of kPointsPerChunk rows
// and observations one row per keyframe, because a row per point or per observation costs
// ~50 B of SQLite overhead and a B-tree step each, which would make loading a million-point map
// take seconds; a chunk is one memcpy. Chunks are also the pages a server reads a map larger
// than its memory bound in (OpenPagedMap): 1024 points (~100 kB) keep a keyframe region's read
// small. Readers take any chunk size (files before paging hold 8192). BLOBs hold little-endian
// arrays (meta 'byte_order').
inline constexpr const char* kSchemaSql = R"sql(
CREATE TABLE meta (
  key TEXT PRIMARY KEY NOT NULL,
  value TEXT NOT NULL
) WITHOUT ROWID;
CREATE TABLE camera (
  id INTEGER PRIMARY KEY CHECK (id = 0),
  model TEXT NOT NULL,
  width INTEGER NOT NULL CHECK (width > 0),
  height INTEGER NOT NULL CHECK (height > 0),
  fx REAL NOT NULL, fy REAL NOT NULL, cx REAL NOT NULL, cy REAL NOT NULL,
  k1 REAL NOT NULL, k2 REAL NOT NULL, p1 REAL NOT NULL, p2 REAL NOT NULL
);
CREATE TABLE features (
  id INTEGER PRIMARY KEY CHECK (id = 0),
  kind TEXT NOT NULL,
  descriptor_type TEXT NOT NULL,
  descriptor_dim INTEGER NOT NULL CHECK (descriptor_dim > 0)
);
CREATE TABLE feature_params (
  position INTEGER PRIMARY KEY,
  name TEXT NOT NULL UNIQUE,
  value REAL NOT NULL
);
CREATE TABLE keyframes (
  id INTEGER PRIMARY KEY,
  timestamp_ns INTEGER NOT NULL,
  tx REAL NOT NULL, ty REAL NOT NULL, tz REAL NOT NULL,
  qw REAL NOT NULL, qx REAL NOT NULL, qy REAL NOT NULL, qz REAL NOT NULL
);
CREATE TABLE point_chunks (
  id INTEGER PRIMARY KEY,
  first_point INTEGER NOT NULL UNIQUE,
  point_count INTEGER NOT NULL CHECK (point_count > 0),
  positions BLOB NOT NULL,
  quality BLOB NOT NULL,
  descriptors BLOB NOT NULL
);
CREATE TABLE keyframe_observations (
  keyframe_id INTEGER PRIMARY KEY REFERENCES keyframes (id),
  observation_count INTEGER NOT NULL,
  points BLOB NOT NULL,
  pixels BLOB NOT NULL
);
CREATE TABLE visibility_kernel (
  id INTEGER PRIMARY KEY CHECK (id = 0),
  cues TEXT NOT NULL,
  metric BLOB NOT NULL,
  default_k INTEGER NOT NULL,
  default_probability_threshold REAL NOT NULL
);
CREATE TABLE vocabulary (
  id INTEGER PRIMARY KEY CHECK (id = 0),
  branching INTEGER NOT NULL,
  depth INTEGER NOT NULL,
  centroids BLOB NOT NULL,
  word_weights BLOB NOT NULL
);
CREATE TABLE keyframe_appearance (
  keyframe_id INTEGER PRIMARY KEY REFERENCES keyframes (id),
  words BLOB NOT NULL,
  weights BLOB NOT NULL
);
)sql";

inline constexpr const char* kTables[] = {"meta",
                                          "camera",
                                          "features",
                                          "feature_params",
                                          "keyframes",
                                          "point_chunks",
                                          "keyframe_observations",
                                          "visibility_kernel",
                                          "vocabulary",
                                          "keyframe_appearance"};
inline constexpr int kPointsPerChunk = 1024;
inline constexpr const char* kFormatName = "visloc-map";

// ---- Content checksum -------------------------------------------------------------------
// CRC-32 over the map's content in a fixed order, computed from the in-memory Map on both
// write and load, so writer and reader cannot disagree about what is covered.
class Crc {
 public:
  explicit Crc(uint32_t seed = 0) : crc_(seed) {}
  void Add(const void* data, size_t bytes) {
    crc_ = Crc32(std::string_view(static_cast<const char*>(data), bytes), crc_);
  }
  template <typename T>
  void Pod(const T& value) {
    Add(&value, sizeof(value));
  }
  void Text(const std::string& text) {
    Pod(text.size());
    Add(text.data(), text.size());
  }
  void Mat(const cv::Mat& mat) {
    Pod(mat.rows);
    Pod(mat.cols);
    for (int r = 0; r < mat.rows; ++r) Add(mat.ptr(r), mat.cols * mat.elemSize());
  }
  uint32_t value() const { return crc_; }

 private:
  uint32_t crc_ = 0;
};

// The checksum covers, in order: the head (metadata, camera, features, keyframes), the points,
// their descriptors, the observations, and the tail (kernel, vocabulary, appearance). The bulk
// in the middle is added from memory (ContentChecksum), or streamed from the file by
// OpenPagedMap.
void ChecksumHead(const Map& map, Crc& crc);
void ChecksumPoint(const MapPoint& p, Crc& crc);
void ChecksumObservation(const Observation& o, Crc& crc);
void ChecksumTail(const Map& map, Crc& crc);
uint32_t ContentChecksum(const Map& map);

// ---- BLOB packing -----------------------------------------------------------------------
template <typename T>
void Append(std::string& out, const T& value) {
  out.append(reinterpret_cast<const char*>(&value), sizeof(T));
}

// Reads fixed-size records from a BLOB after checking its size.
class BlobReader {
 public:
  BlobReader(std::string_view blob, size_t expected_bytes, const std::string& what,
             const std::string& path)
      : blob_(blob) {
    if (blob.size() != expected_bytes) {
      throw InputError(
          StrCat(path, ": ", what, " has ", blob.size(), " bytes, expected ", expected_bytes));
    }
  }
  template <typename T>
  T Next() {
    T value;
    std::memcpy(&value, blob_.data() + offset_, sizeof(T));
    offset_ += sizeof(T);
    return value;
  }
  const char* data() const { return blob_.data(); }

 private:
  std::string_view blob_;
  size_t offset_ = 0;
};

std::string JoinCues(const std::vector<std::string>& cues);
size_t DescriptorBytes(const FeatureSettings& features);

// ---- Reading (map_read.cc) --------------------------------------------------------------
struct Meta {
  int schema_version = 0;
  uint32_t content_crc = 0;
};
inline constexpr const char* kPointChunkColumns =
    "SELECT id, first_point, point_count, positions, quality, descriptors FROM point_chunks";
inline constexpr const char* kObservationColumns =
    "SELECT keyframe_id, observation_count, points, pixels FROM keyframe_observations";

// Throws InputError "<path>: <problem>" for a missing or empty file.
void CheckFileExists(const std::string& path);
Meta ReadMeta(Database& db, Map* map);
void RequireTables(Database& db);
void ReadCameraAndFeatures(Database& db, Map* map);
void ReadKeyframes(Database& db, Map* map);
// Counts read from the file decide allocations, so a damaged count must not ask for more
// memory than the file could describe: each item takes at least `min_bytes_each` bytes of it.
void CheckCountFitsTheFile(const Database& db, const char* what, int64_t count,
                           size_t min_bytes_each);
// The total point count, checked against the file's size.
int64_t PointCount(Database& db, const FeatureSettings& features);
// One row of kPointChunkColumns: points [first, first + n) of `total`; `next` is where the
// previous chunk ended (chunks are contiguous), or -1 when the row was looked up by id.
PointChunk ParsePointChunk(Statement& row, const FeatureSettings& features, int64_t total,
                           int64_t next, const std::string& path);
void ReadPoints(Database& db, Map* map);
// One row of kObservationColumns: the observations of one keyframe, in the stored order.
std::vector<Observation> ParseObservations(Statement& row, size_t keyframe_count,
                                           const std::string& path);
int64_t ObservationCount(Database& db);
void ReadObservations(Database& db, Map* map);
void ReadKernelAndAppearance(Database& db, Map* map);

}  // namespace visloc::mapstore::internal
