#include "mapstore/map_store.h"

#include <fcntl.h>
#include <unistd.h>
#include <zlib.h>

#include <atomic>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <mutex>

#include "core/map/localization_map.h"
#include "core/map/map_pages.h"
#include "core/util/check.h"
#include "core/util/strings.h"
#include "mapstore/checksum.h"
#include "mapstore/file_sync.h"
#include "mapstore/sqlite.h"

namespace visloc::mapstore {
namespace fs = std::filesystem;
namespace {

static_assert(sizeof(float) == 4 && sizeof(double) == 8, "IEEE floats expected");

// Schema version 1. Bulk data is packed into BLOBs: points in chunks of kPointsPerChunk rows
// and observations one row per keyframe, because a row per point or per observation costs
// ~50 B of SQLite overhead and a B-tree step each, which would make loading a million-point map
// take seconds; a chunk is one memcpy. Chunks are also the pages a server reads a map larger
// than its memory bound in (OpenPagedMap): 1024 points (~100 kB) keep a keyframe region's read
// small. Readers take any chunk size (files before paging hold 8192). BLOBs hold little-endian
// arrays (meta 'byte_order').
constexpr const char* kSchemaSql = R"sql(
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

constexpr const char* kTables[] = {"meta",
                                   "camera",
                                   "features",
                                   "feature_params",
                                   "keyframes",
                                   "point_chunks",
                                   "keyframe_observations",
                                   "visibility_kernel",
                                   "vocabulary",
                                   "keyframe_appearance"};
constexpr int kPointsPerChunk = 1024;
constexpr const char* kFormatName = "visloc-map";

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

}  // namespace

const char* CameraModelName(LensModel model) {
  return model == LensModel::kEquidistant ? "pinhole-equidistant" : "pinhole-radtan";
}

namespace {

// The checksum covers, in order: the head (metadata, camera, features, keyframes), the points,
// their descriptors, the observations, and the tail (kernel, vocabulary, appearance). The bulk
// in the middle is added from memory here, or streamed from the file by OpenPagedMap.
void ChecksumHead(const Map& map, Crc& crc) {
  crc.Text(map.metadata.name);
  crc.Pod(map.metadata.created_unix_s);
  crc.Text(map.metadata.source_dataset);
  crc.Text(map.metadata.builder);
  // Maps of one build checksum as before lineage existed.
  if (!map.metadata.lineage.empty()) crc.Text(map.metadata.lineage);
  crc.Pod(map.camera.width());
  crc.Pod(map.camera.height());
  crc.Pod(map.camera.Params());
  // Radial-tangential maps checksum as before lens models existed.
  if (map.camera.lens().model != LensModel::kRadialTangential) {
    crc.Text(CameraModelName(map.camera.lens().model));
  }
  crc.Text(map.features.kind);
  crc.Pod(map.features.descriptor_type);
  crc.Pod(map.features.descriptor_dim);
  for (const auto& [name, value] : map.features.params) {
    crc.Text(name);
    crc.Pod(value);
  }
  for (const Keyframe& k : map.keyframes) {
    crc.Pod(k.timestamp_ns);
    crc.Add(k.map_from_cam.translation.data(), 3 * sizeof(double));
    crc.Add(k.map_from_cam.rotation.coeffs().data(), 4 * sizeof(double));
  }
}

void ChecksumPoint(const MapPoint& p, Crc& crc) {
  crc.Add(p.position_in_map.data(), 3 * sizeof(double));
  crc.Pod(p.observation_count);
  crc.Pod(p.mean_reproj_error_px);
}

void ChecksumObservation(const Observation& o, Crc& crc) {
  crc.Pod(o.keyframe);
  crc.Pod(o.point);
  crc.Add(o.pixel.data(), 2 * sizeof(float));
}

void ChecksumTail(const Map& map, Crc& crc) {
  for (const std::string& cue : map.kernel.cues) crc.Text(cue);
  crc.Add(map.kernel.metric.data(), map.kernel.metric.size() * sizeof(double));
  crc.Pod(map.kernel.default_k);
  crc.Pod(map.kernel.default_probability_threshold);
  const Vocabulary& vocabulary = map.appearance.vocabulary;
  crc.Pod(vocabulary.branching);
  crc.Pod(vocabulary.depth);
  crc.Mat(vocabulary.centroids);
  crc.Add(vocabulary.word_weights.data(), vocabulary.word_weights.size() * sizeof(float));
  for (const BowVector& v : map.appearance.keyframe_vectors) {
    crc.Pod(v.size());
    for (const auto& [word, weight] : v) {
      crc.Pod(word);
      crc.Pod(weight);
    }
  }
}

uint32_t ContentChecksum(const Map& map) {
  Crc crc;
  ChecksumHead(map, crc);
  for (const MapPoint& p : map.points) ChecksumPoint(p, crc);
  crc.Mat(map.descriptors);
  for (const Observation& o : map.observations) ChecksumObservation(o, crc);
  ChecksumTail(map, crc);
  return crc.value();
}

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

std::string JoinCues(const std::vector<std::string>& cues) {
  std::string out;
  for (const std::string& cue : cues) out += (out.empty() ? "" : ",") + cue;
  return out;
}

size_t DescriptorBytes(const FeatureSettings& features) {
  return features.descriptor_dim * (features.descriptor_type == DescriptorType::kFloat32 ? 4 : 1);
}

// ---- Writing ----------------------------------------------------------------------------
void WriteMeta(Database& db, const Map& map) {
  Statement insert = db.Prepare("INSERT INTO meta (key, value) VALUES (?, ?)");
  const std::pair<std::string, std::string> rows[] = {
      {"format", kFormatName},
      {"schema_version", std::to_string(SchemaVersionOf(map))},
      {"byte_order", "little"},
      {"name", map.metadata.name},
      {"created_unix_s", std::to_string(map.metadata.created_unix_s)},
      {"source_dataset", map.metadata.source_dataset},
      {"builder", map.metadata.builder},
      {"content_crc32", std::to_string(ContentChecksum(map))},
  };
  for (const auto& [key, value] : rows) insert.Bind(1, key).Bind(2, value).Run();
  if (!map.metadata.lineage.empty()) insert.Bind(1, std::string("lineage")).Bind(2, map.metadata.lineage).Run();
}

void WriteCameraAndFeatures(Database& db, const Map& map) {
  const auto p = map.camera.Params();
  Statement camera =
      db.Prepare("INSERT INTO camera VALUES (0, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)");
  camera.Bind(1, std::string(CameraModelName(map.camera.lens().model)))
      .Bind(2, static_cast<int64_t>(map.camera.width()))
      .Bind(3, static_cast<int64_t>(map.camera.height()));
  for (int i = 0; i < 8; ++i) camera.Bind(4 + i, p[i]);
  camera.Run();
  db.Prepare("INSERT INTO features VALUES (0, ?, ?, ?)")
      .Bind(1, map.features.kind)
      .Bind(2, ToString(map.features.descriptor_type))
      .Bind(3, static_cast<int64_t>(map.features.descriptor_dim))
      .Run();
  Statement param = db.Prepare("INSERT INTO feature_params VALUES (?, ?, ?)");
  for (size_t i = 0; i < map.features.params.size(); ++i) {
    param.Bind(1, static_cast<int64_t>(i))
        .Bind(2, map.features.params[i].first)
        .Bind(3, map.features.params[i].second)
        .Run();
  }
}

void WriteKeyframes(Database& db, const Map& map) {
  Statement insert = db.Prepare("INSERT INTO keyframes VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)");
  for (size_t i = 0; i < map.keyframes.size(); ++i) {
    const Rigid3d& pose = map.keyframes[i].map_from_cam;
    insert.Bind(1, static_cast<int64_t>(i)).Bind(2, map.keyframes[i].timestamp_ns);
    insert.Bind(3, pose.translation.x())
        .Bind(4, pose.translation.y())
        .Bind(5, pose.translation.z());
    insert.Bind(6, pose.rotation.w())
        .Bind(7, pose.rotation.x())
        .Bind(8, pose.rotation.y())
        .Bind(9, pose.rotation.z());
    insert.Run();
  }
}

void WritePoints(Database& db, const Map& map) {
  Statement insert = db.Prepare("INSERT INTO point_chunks VALUES (?, ?, ?, ?, ?, ?)");
  const size_t descriptor_bytes = DescriptorBytes(map.features);
  const int total = static_cast<int>(map.points.size());
  for (int first = 0, chunk = 0; first < total; first += kPointsPerChunk, ++chunk) {
    const int count = std::min(kPointsPerChunk, total - first);
    std::string positions, quality, descriptors;
    positions.reserve(count * 24);
    quality.reserve(count * 8);
    descriptors.reserve(count * descriptor_bytes);
    for (int j = first; j < first + count; ++j) {
      const MapPoint& point = map.points[j];
      positions.append(reinterpret_cast<const char*>(point.position_in_map.data()), 24);
      Append(quality, point.observation_count);
      Append(quality, point.mean_reproj_error_px);
      descriptors.append(reinterpret_cast<const char*>(map.descriptors.ptr(j)), descriptor_bytes);
    }
    insert.Bind(1, static_cast<int64_t>(chunk))
        .Bind(2, static_cast<int64_t>(first))
        .Bind(3, static_cast<int64_t>(count));
    insert.BindBlob(4, positions.data(), positions.size());
    insert.BindBlob(5, quality.data(), quality.size());
    insert.BindBlob(6, descriptors.data(), descriptors.size());
    insert.Run();
  }
}

void WriteObservations(Database& db, const Map& map) {
  Statement insert = db.Prepare("INSERT INTO keyframe_observations VALUES (?, ?, ?, ?)");
  size_t i = 0;
  for (size_t k = 0; k < map.keyframes.size(); ++k) {
    std::string points, pixels;
    for (; i < map.observations.size() && map.observations[i].keyframe == k; ++i) {
      Append(points, map.observations[i].point);
      pixels.append(reinterpret_cast<const char*>(map.observations[i].pixel.data()), 8);
    }
    insert.Bind(1, static_cast<int64_t>(k)).Bind(2, static_cast<int64_t>(points.size() / 4));
    insert.BindBlob(3, points.data(), points.size()).BindBlob(4, pixels.data(), pixels.size());
    insert.Run();
  }
}

void WriteKernelAndAppearance(Database& db, const Map& map) {
  const VisibilityKernel& kernel = map.kernel;
  db.Prepare("INSERT INTO visibility_kernel VALUES (0, ?, ?, ?, ?)")
      .Bind(1, JoinCues(kernel.cues))
      .BindBlob(2, kernel.metric.data(), kernel.metric.size() * sizeof(double))
      .Bind(3, static_cast<int64_t>(kernel.default_k))
      .Bind(4, kernel.default_probability_threshold)
      .Run();
  const Vocabulary& vocabulary = map.appearance.vocabulary;
  if (!vocabulary.empty()) {
    const cv::Mat centroids =
        vocabulary.centroids.isContinuous() ? vocabulary.centroids : vocabulary.centroids.clone();
    db.Prepare("INSERT INTO vocabulary VALUES (0, ?, ?, ?, ?)")
        .Bind(1, static_cast<int64_t>(vocabulary.branching))
        .Bind(2, static_cast<int64_t>(vocabulary.depth))
        .BindBlob(3, centroids.data, centroids.total() * centroids.elemSize())
        .BindBlob(4, vocabulary.word_weights.data(), vocabulary.word_weights.size() * sizeof(float))
        .Run();
  }
  Statement insert = db.Prepare("INSERT INTO keyframe_appearance VALUES (?, ?, ?)");
  for (size_t k = 0; k < map.appearance.keyframe_vectors.size(); ++k) {
    std::string words, weights;
    for (const auto& [word, weight] : map.appearance.keyframe_vectors[k]) {
      Append(words, word);
      Append(weights, weight);
    }
    insert.Bind(1, static_cast<int64_t>(k))
        .BindBlob(2, words.data(), words.size())
        .BindBlob(3, weights.data(), weights.size());
    insert.Run();
  }
}

// ---- Reading ----------------------------------------------------------------------------
struct Meta {
  int schema_version = 0;
  uint32_t content_crc = 0;
};

Meta ReadMeta(Database& db, Map* map) {
  if (!db.HasTable("meta")) throw InputError(db.path() + ": not a visloc map (no 'meta' table)");
  std::vector<std::pair<std::string, std::string>> rows;
  Statement query = db.Prepare("SELECT key, value FROM meta");
  while (query.Step()) rows.emplace_back(query.ColumnText(0), query.ColumnText(1));
  auto value = [&](const std::string& key) -> std::string {
    for (const auto& [k, v] : rows) {
      if (k == key) return v;
    }
    throw InputError(StrCat(db.path(), ": meta has no '", key, "'"));
  };
  if (value("format") != kFormatName) {
    throw InputError(StrCat(db.path(), ": not a visloc map (format '", value("format"), "')"));
  }
  Meta meta;
  const auto version = ParseInt64(value("schema_version"));
  if (!version)
    throw InputError(db.path() + ": bad schema_version '" + value("schema_version") + "'");
  meta.schema_version = static_cast<int>(*version);
  if (meta.schema_version > kMapSchemaVersion) {
    throw InputError(StrCat(db.path(), ": written by a newer visloc (map schema ",
                            meta.schema_version, "; this visloc reads up to ", kMapSchemaVersion,
                            "): upgrade visloc"));
  }
  if (meta.schema_version < 1) {
    throw InputError(StrCat(db.path(), ": unknown map schema ", meta.schema_version));
  }
  if (value("byte_order") != "little") throw InputError(db.path() + ": unsupported byte order");
  map->metadata.name = value("name");
  map->metadata.source_dataset = value("source_dataset");
  map->metadata.builder = value("builder");
  for (const auto& [k, v] : rows) {
    if (k == "lineage") map->metadata.lineage = v;  // Schema 2; optional.
  }
  const auto created = ParseInt64(value("created_unix_s"));
  const auto crc = ParseInt64(value("content_crc32"));
  if (!created || !crc || *crc < 0 || *crc > 0xffffffffLL) {
    throw InputError(db.path() + ": malformed meta values");
  }
  map->metadata.created_unix_s = *created;
  meta.content_crc = static_cast<uint32_t>(*crc);
  return meta;
}

void RequireTables(Database& db) {
  for (const char* table : kTables) {
    if (!db.HasTable(table)) throw InputError(StrCat(db.path(), ": missing table '", table, "'"));
  }
}

void ReadCameraAndFeatures(Database& db, Map* map) {
  Statement camera =
      db.Prepare("SELECT model, width, height, fx, fy, cx, cy, k1, k2, p1, p2 FROM camera");
  if (!camera.Step()) throw InputError(db.path() + ": no camera");
  const std::string model = camera.ColumnText(0);
  if (model != CameraModelName(LensModel::kRadialTangential) &&
      model != CameraModelName(LensModel::kEquidistant)) {
    throw InputError(StrCat(db.path(), ": unsupported camera model '", model, "'"));
  }
  double p[8];
  for (int i = 0; i < 8; ++i) p[i] = camera.ColumnDouble(3 + i);
  const Lens lens = model == CameraModelName(LensModel::kEquidistant)
                        ? Lens::Equidistant(p[4], p[5], p[6], p[7])
                        : Lens(p[4], p[5], p[6], p[7]);
  try {
    map->camera = Camera(static_cast<int>(camera.ColumnInt64(1)),
                         static_cast<int>(camera.ColumnInt64(2)), p[0], p[1], p[2], p[3], lens);
  } catch (const CheckError& e) {
    throw InputError(StrCat(db.path(), ": invalid camera: ", e.what()));
  }
  Statement features = db.Prepare("SELECT kind, descriptor_type, descriptor_dim FROM features");
  if (!features.Step()) throw InputError(db.path() + ": no feature settings");
  map->features.kind = features.ColumnText(0);
  try {
    map->features.descriptor_type = ParseDescriptorType(features.ColumnText(1));
  } catch (const InputError& e) {
    throw InputError(db.path() + ": " + e.what());
  }
  const int64_t dim = features.ColumnInt64(2);
  if (dim <= 0 || dim > 4096) throw InputError(StrCat(db.path(), ": descriptor dimension ", dim));
  map->features.descriptor_dim = static_cast<int>(dim);
  Statement params = db.Prepare("SELECT name, value FROM feature_params ORDER BY position");
  while (params.Step())
    map->features.params.emplace_back(params.ColumnText(0), params.ColumnDouble(1));
}

void ReadKeyframes(Database& db, Map* map) {
  Statement query =
      db.Prepare("SELECT id, timestamp_ns, tx, ty, tz, qw, qx, qy, qz FROM keyframes ORDER BY id");
  while (query.Step()) {
    if (query.ColumnInt64(0) != static_cast<int64_t>(map->keyframes.size())) {
      throw InputError(
          StrCat(db.path(), ": keyframe ids are not 0..N-1 (found ", query.ColumnInt64(0), ")"));
    }
    Keyframe keyframe;
    keyframe.timestamp_ns = query.ColumnInt64(1);
    keyframe.map_from_cam.translation =
        Eigen::Vector3d(query.ColumnDouble(2), query.ColumnDouble(3), query.ColumnDouble(4));
    // Stored as written; no renormalization, so a broken quaternion is reported, not hidden.
    keyframe.map_from_cam.rotation.coeffs() << query.ColumnDouble(6), query.ColumnDouble(7),
        query.ColumnDouble(8), query.ColumnDouble(5);
    map->keyframes.push_back(keyframe);
  }
}

// Counts read from the file decide allocations, so a damaged count must not ask for more
// memory than the file could describe: each item takes at least `min_bytes_each` bytes of it.
void CheckCountFitsTheFile(const Database& db, const char* what, int64_t count,
                           size_t min_bytes_each) {
  std::error_code error;
  const uintmax_t file_bytes = fs::file_size(db.path(), error);
  if (count < 0 || (!error && static_cast<uintmax_t>(count) > file_bytes / min_bytes_each)) {
    throw InputError(StrCat(db.path(), ": ", what, " count ", count, " does not fit in a file of ",
                            error ? 0 : file_bytes, " bytes"));
  }
}

// The total point count, checked against the file's size.
int64_t PointCount(Database& db, const FeatureSettings& features) {
  Statement count = db.Prepare("SELECT COALESCE(SUM(point_count), 0) FROM point_chunks");
  count.Step();
  const int64_t total = count.ColumnInt64(0);
  if (total < 0 || total > (int64_t{1} << 31))
    throw InputError(StrCat(db.path(), ": point count ", total));
  // A point's position (24 bytes) and quality (8) and descriptor are stored in its chunk.
  CheckCountFitsTheFile(db, "point", total, 32 + DescriptorBytes(features));
  return total;
}

constexpr const char* kPointChunkColumns =
    "SELECT id, first_point, point_count, positions, quality, descriptors FROM point_chunks";

// One row of kPointChunkColumns: points [first, first + n) of `total`; `next` is where the
// previous chunk ended (chunks are contiguous), or -1 when the row was looked up by id.
PointChunk ParsePointChunk(Statement& row, const FeatureSettings& features, int64_t total,
                           int64_t next, const std::string& path) {
  const int64_t chunk = row.ColumnInt64(0), first = row.ColumnInt64(1), n = row.ColumnInt64(2);
  if ((next >= 0 && first != next) || first < 0 || n <= 0 || first + n > total) {
    throw InputError(StrCat(path, ": point chunk ", chunk, " covers points ", first, "+", n,
                            ", expected to start at ", next, " (of ", total, ")"));
  }
  const size_t descriptor_bytes = DescriptorBytes(features);
  const std::string what = StrCat("point chunk ", chunk);
  BlobReader positions(row.ColumnBlob(3), n * 24, what + " positions", path);
  BlobReader quality(row.ColumnBlob(4), n * 8, what + " quality", path);
  BlobReader descriptors(row.ColumnBlob(5), n * descriptor_bytes, what + " descriptors", path);
  PointChunk out;
  out.first = static_cast<uint32_t>(first);
  out.points.resize(n);
  for (MapPoint& point : out.points) {
    point.position_in_map.x() = positions.Next<double>();
    point.position_in_map.y() = positions.Next<double>();
    point.position_in_map.z() = positions.Next<double>();
    point.observation_count = quality.Next<uint32_t>();
    point.mean_reproj_error_px = quality.Next<float>();
  }
  out.descriptors = cv::Mat(static_cast<int>(n), features.descriptor_dim, features.cv_type());
  std::memcpy(out.descriptors.data, descriptors.data(), n * descriptor_bytes);
  return out;
}

void ReadPoints(Database& db, Map* map) {
  const int64_t total = PointCount(db, map->features);
  map->points.resize(total);
  map->descriptors =
      cv::Mat(static_cast<int>(total), map->features.descriptor_dim, map->features.cv_type());
  Statement query = db.Prepare(StrCat(kPointChunkColumns, " ORDER BY id"));
  int64_t next = 0;
  while (query.Step()) {
    const PointChunk chunk = ParsePointChunk(query, map->features, total, next, db.path());
    std::copy(chunk.points.begin(), chunk.points.end(), map->points.begin() + chunk.first);
    chunk.descriptors.copyTo(map->descriptors.rowRange(
        static_cast<int>(chunk.first), static_cast<int>(chunk.first + chunk.points.size())));
    next = chunk.first + chunk.points.size();
  }
}

constexpr const char* kObservationColumns =
    "SELECT keyframe_id, observation_count, points, pixels FROM keyframe_observations";

// One row of kObservationColumns: the observations of one keyframe, in the stored order.
std::vector<Observation> ParseObservations(Statement& row, size_t keyframe_count,
                                           const std::string& path) {
  const int64_t keyframe = row.ColumnInt64(0), n = row.ColumnInt64(1);
  if (keyframe < 0 || keyframe >= static_cast<int64_t>(keyframe_count) || n < 0 ||
      n > (int64_t{1} << 28)) {
    throw InputError(StrCat(path, ": observations of keyframe ", keyframe, " (", n,
                            ") do not match the ", keyframe_count, " keyframes"));
  }
  const std::string what = StrCat("observations of keyframe ", keyframe);
  BlobReader points(row.ColumnBlob(2), n * 4, what, path);
  BlobReader pixels(row.ColumnBlob(3), n * 8, what + " pixels", path);
  std::vector<Observation> out(n);
  for (Observation& o : out) {
    o.keyframe = static_cast<uint32_t>(keyframe);
    o.point = points.Next<uint32_t>();
    o.pixel.x() = pixels.Next<float>();
    o.pixel.y() = pixels.Next<float>();
  }
  return out;
}

int64_t ObservationCount(Database& db) {
  Statement total =
      db.Prepare("SELECT COALESCE(SUM(observation_count), 0) FROM keyframe_observations");
  total.Step();
  // An observation stores a point id (4 bytes) and a pixel (8).
  CheckCountFitsTheFile(db, "observation", total.ColumnInt64(0), 12);
  return total.ColumnInt64(0);
}

void ReadObservations(Database& db, Map* map) {
  map->observations.reserve(static_cast<size_t>(ObservationCount(db)));
  Statement query = db.Prepare(StrCat(kObservationColumns, " ORDER BY keyframe_id"));
  while (query.Step()) {
    for (const Observation& o : ParseObservations(query, map->keyframes.size(), db.path())) {
      map->observations.push_back(o);
    }
  }
}

void ReadKernelAndAppearance(Database& db, Map* map) {
  Statement kernel = db.Prepare(
      "SELECT cues, metric, default_k, default_probability_threshold FROM visibility_kernel");
  if (!kernel.Step()) throw InputError(db.path() + ": no visibility kernel");
  const std::string cues = kernel.ColumnText(0);
  if (!cues.empty()) map->kernel.cues = Split(cues, ',');
  const size_t n = map->kernel.cues.size();
  const std::string_view metric = kernel.ColumnBlob(1);
  if (!metric.empty()) {
    BlobReader reader(metric, n * n * sizeof(double), "visibility kernel metric", db.path());
    map->kernel.metric.resize(n, n);
    std::memcpy(map->kernel.metric.data(), reader.data(), n * n * sizeof(double));
  }
  map->kernel.default_k = static_cast<int>(kernel.ColumnInt64(2));
  map->kernel.default_probability_threshold = kernel.ColumnDouble(3);

  Statement vocabulary =
      db.Prepare("SELECT branching, depth, centroids, word_weights FROM vocabulary");
  if (vocabulary.Step()) {
    Vocabulary& v = map->appearance.vocabulary;
    v.branching = static_cast<int>(vocabulary.ColumnInt64(0));
    v.depth = static_cast<int>(vocabulary.ColumnInt64(1));
    if (v.branching < 2 || v.depth < 1 || std::pow(v.branching, v.depth) > 1e7) {
      throw InputError(
          StrCat(db.path(), ": vocabulary of branching ", v.branching, " and depth ", v.depth));
    }
    size_t nodes = 0, level = 1;
    for (int d = 0; d < v.depth; ++d) nodes += (level *= v.branching);
    const size_t row_bytes = DescriptorBytes(map->features);
    BlobReader centroids(vocabulary.ColumnBlob(2), nodes * row_bytes, "vocabulary centroids",
                         db.path());
    v.centroids =
        cv::Mat(static_cast<int>(nodes), map->features.descriptor_dim, map->features.cv_type());
    std::memcpy(v.centroids.data, centroids.data(), nodes * row_bytes);
    BlobReader weights(vocabulary.ColumnBlob(3), level * sizeof(float), "vocabulary word weights",
                       db.path());
    v.word_weights.resize(level);
    std::memcpy(v.word_weights.data(), weights.data(), level * sizeof(float));
  }
  Statement appearance = db.Prepare(
      "SELECT keyframe_id, words, weights FROM keyframe_appearance ORDER BY keyframe_id");
  while (appearance.Step()) {
    if (appearance.ColumnInt64(0) !=
        static_cast<int64_t>(map->appearance.keyframe_vectors.size())) {
      throw InputError(StrCat(db.path(), ": appearance rows are not one per keyframe in order"));
    }
    const std::string_view words = appearance.ColumnBlob(1);
    const size_t count = words.size() / 4;
    const std::string what = StrCat("appearance of keyframe ", appearance.ColumnInt64(0));
    BlobReader word_reader(words, count * 4, what, db.path());
    BlobReader weight_reader(appearance.ColumnBlob(2), count * 4, what + " weights", db.path());
    BowVector vector(count);
    for (auto& [word, weight] : vector) {
      word = word_reader.Next<uint32_t>();
      weight = weight_reader.Next<float>();
    }
    map->appearance.keyframe_vectors.push_back(std::move(vector));
  }
}

void CheckFileExists(const std::string& path) {
  std::error_code error;
  if (!fs::is_regular_file(path, error)) throw InputError(StrCat(path, ": no such map file"));
  if (fs::file_size(path, error) == 0)
    throw InputError(StrCat(path, ": empty file, not a visloc map"));
}

}  // namespace

void SaveMap(const Map& map, const std::string& path, const SaveMapOptions& options) {
  const int page = options.page_size_bytes;
  VISLOC_CHECK(page >= 512 && page <= 65536 && (page & (page - 1)) == 0, "page size ", page);
  const auto problems = FindMapProblems(map, 1);
  VISLOC_CHECK(problems.empty(),
               "refusing to write an inconsistent map: ", problems.empty() ? "" : problems[0]);
  const fs::path folder =
      fs::path(path).has_parent_path() ? fs::path(path).parent_path() : fs::path(".");
  if (!fs::is_directory(folder))
    throw InputError(StrCat(path, ": folder ", folder.string(), " does not exist"));
  const std::string temp = TemporaryPathBeside(path);
  try {
    {
      Database db = Database::OpenForWriting(temp);
      // The temporary file is discarded on any failure, so its journal can live in memory;
      // FULL sync makes COMMIT durable before the rename publishes the file.
      db.Exec(StrCat("PRAGMA page_size = ", page,
                     "; PRAGMA journal_mode = MEMORY; PRAGMA synchronous = FULL;"));
      Transaction transaction(db);
      db.Exec(kSchemaSql);
      WriteMeta(db, map);
      WriteCameraAndFeatures(db, map);
      WriteKeyframes(db, map);
      WritePoints(db, map);
      WriteObservations(db, map);
      WriteKernelAndAppearance(db, map);
      transaction.Commit();
    }
    SyncPath(temp, O_RDONLY);
    if (std::rename(temp.c_str(), path.c_str()) != 0) {
      throw InputError(
          StrCat(path, ": cannot move the new map into place: ", std::strerror(errno)));
    }
    const fs::path parent =
        fs::path(path).has_parent_path() ? fs::path(path).parent_path() : fs::path(".");
    SyncPath(parent.string(), O_RDONLY | O_DIRECTORY);
  } catch (...) {
    std::error_code ignored;
    fs::remove(temp, ignored);
    throw;
  }
}

Map LoadMap(const std::string& path) {
  CheckFileExists(path);
  Database db = Database::OpenReadOnly(path);
  Map map;
  const Meta meta = ReadMeta(db, &map);
  RequireTables(db);
  ReadCameraAndFeatures(db, &map);
  ReadKeyframes(db, &map);
  ReadPoints(db, &map);
  ReadObservations(db, &map);
  ReadKernelAndAppearance(db, &map);
  const auto problems = FindMapProblems(map, 1);
  if (!problems.empty()) throw InputError(StrCat(path, ": ", problems[0]));
  if (ContentChecksum(map) != meta.content_crc) {
    throw InputError(
        StrCat(path, ": content checksum mismatch: the file is corrupt or was modified"));
  }
  return map;
}

namespace {

// Pages of one map file, read under a lock through the connection OpenPagedMap verified with.
class FilePageSource final : public MapPageSource {
 public:
  FilePageSource(Database db, const Map& skeleton, uint32_t points, uint32_t chunk_points,
                 size_t bulk_bytes)
      : db_(std::move(db)),
        features_(skeleton.features),
        keyframes_(skeleton.keyframes.size()),
        points_(points),
        chunk_points_(chunk_points),
        bulk_bytes_(bulk_bytes) {}

  uint32_t point_count() const override { return points_; }
  uint32_t chunk_points() const override { return chunk_points_; }
  size_t BulkBytes() const override { return bulk_bytes_; }

  PointChunk LoadPointChunk(uint32_t chunk) const override {
    std::lock_guard<std::mutex> lock(mutex_);
    Statement query = db_.Prepare(StrCat(kPointChunkColumns, " WHERE id = ?"));
    query.Bind(1, static_cast<int64_t>(chunk));
    if (!query.Step()) throw InputError(StrCat(db_.path(), ": no point chunk ", chunk));
    PointChunk out = ParsePointChunk(query, features_, points_, -1, db_.path());
    if (out.first != static_cast<uint64_t>(chunk) * chunk_points_) {
      throw InputError(StrCat(db_.path(), ": point chunk ", chunk, " starts at ", out.first));
    }
    return out;
  }

  std::vector<uint32_t> LoadVisiblePoints(uint32_t keyframe) const override {
    std::lock_guard<std::mutex> lock(mutex_);
    Statement query = db_.Prepare(StrCat(kObservationColumns, " WHERE keyframe_id = ?"));
    query.Bind(1, static_cast<int64_t>(keyframe));
    std::vector<uint32_t> ids;
    if (!query.Step()) return ids;  // A keyframe that sees nothing.
    for (const Observation& o : ParseObservations(query, keyframes_, db_.path()))
      ids.push_back(o.point);
    return ids;
  }

 private:
  mutable std::mutex mutex_;
  mutable Database db_;
  FeatureSettings features_;
  size_t keyframes_;
  uint32_t points_;
  uint32_t chunk_points_;
  size_t bulk_bytes_;
};

bool FinitePoint(const MapPoint& p) {
  return p.position_in_map.allFinite() && std::isfinite(p.mean_reproj_error_px);
}

// Streams the points into the checksum (and their descriptors into a second one, combined
// after: the checksum covers all points before all descriptors). Returns each point's stored
// observation count; sets the chunk size, which every chunk but the last must fill.
std::vector<uint32_t> VerifyPoints(Database& db, const Map& skeleton, int64_t total, Crc& crc,
                                   uint32_t* chunk_points) {
  std::vector<uint32_t> counts(total);
  Crc descriptors;
  descriptors.Pod(static_cast<int>(total));
  descriptors.Pod(skeleton.features.descriptor_dim);
  size_t descriptor_bytes = 2 * sizeof(int);
  Statement query = db.Prepare(StrCat(kPointChunkColumns, " ORDER BY id"));
  int64_t next = 0;
  *chunk_points = 0;
  while (query.Step()) {
    const PointChunk chunk = ParsePointChunk(query, skeleton.features, total, next, db.path());
    if (*chunk_points == 0) *chunk_points = static_cast<uint32_t>(chunk.points.size());
    if (chunk.first % *chunk_points != 0 ||
        (chunk.points.size() != *chunk_points &&
         chunk.first + chunk.points.size() != static_cast<uint64_t>(total))) {
      throw InputError(StrCat(db.path(), ": point chunk at ", chunk.first, " holds ",
                              chunk.points.size(),
                              " points; paged serving needs chunks of one size"));
    }
    for (size_t i = 0; i < chunk.points.size(); ++i) {
      const MapPoint& point = chunk.points[i];
      if (!FinitePoint(point))
        throw InputError(StrCat(db.path(), ": point ", chunk.first + i, " is not finite"));
      ChecksumPoint(point, crc);
      counts[chunk.first + i] = point.observation_count;
    }
    const size_t bytes = chunk.descriptors.total() * chunk.descriptors.elemSize();
    descriptors.Add(chunk.descriptors.data, bytes);
    descriptor_bytes += bytes;
    next = chunk.first + chunk.points.size();
  }
  if (next != total)
    throw InputError(StrCat(db.path(), ": point chunks end at ", next, " of ", total));
  crc = Crc(static_cast<uint32_t>(
      crc32_combine(crc.value(), descriptors.value(), static_cast<z_off_t>(descriptor_bytes))));
  return counts;
}

// Streams the observations into the checksum, checking each against the points: in range,
// sorted within its keyframe, finite, and as many per point as the point says.
void VerifyObservations(Database& db, const Map& skeleton, std::vector<uint32_t> counts, Crc& crc) {
  Statement query = db.Prepare(StrCat(kObservationColumns, " ORDER BY keyframe_id"));
  while (query.Step()) {
    const std::vector<Observation> observations =
        ParseObservations(query, skeleton.keyframes.size(), db.path());
    for (size_t i = 0; i < observations.size(); ++i) {
      const Observation& o = observations[i];
      const std::string which = StrCat(db.path(), ": observation ", i, " of keyframe ", o.keyframe);
      if (o.point >= counts.size()) {
        throw InputError(StrCat(which, " refers to point ", o.point, " but the map has ",
                                counts.size(), " points"));
      }
      if (!o.pixel.allFinite() || (i > 0 && observations[i - 1].point >= o.point)) {
        throw InputError(StrCat(which, " is not finite or not in point order"));
      }
      if (counts[o.point] == 0) {
        throw InputError(
            StrCat(db.path(), ": point ", o.point, " has more observations than it counts"));
      }
      --counts[o.point];
      ChecksumObservation(o, crc);
    }
  }
  for (size_t p = 0; p < counts.size(); ++p) {
    if (counts[p] != 0) {
      throw InputError(StrCat(db.path(), ": point ", p, " has fewer observations than it counts"));
    }
  }
}

}  // namespace

PagedMap OpenPagedMap(const std::string& path) {
  CheckFileExists(path);
  Database db = Database::OpenReadOnly(path);
  PagedMap paged;
  Map& skeleton = paged.skeleton;
  const Meta meta = ReadMeta(db, &skeleton);
  RequireTables(db);
  ReadCameraAndFeatures(db, &skeleton);
  ReadKeyframes(db, &skeleton);
  ReadKernelAndAppearance(db, &skeleton);
  skeleton.descriptors = cv::Mat(0, skeleton.features.descriptor_dim, skeleton.features.cv_type());
  const auto problems = FindMapProblems(skeleton, 1);
  if (!problems.empty()) throw InputError(StrCat(path, ": ", problems[0]));
  const int64_t total = PointCount(db, skeleton.features);
  const int64_t observations = ObservationCount(db);
  Crc crc;
  ChecksumHead(skeleton, crc);
  uint32_t chunk_points = 0;
  VerifyObservations(db, skeleton, VerifyPoints(db, skeleton, total, crc, &chunk_points), crc);
  ChecksumTail(skeleton, crc);
  if (crc.value() != meta.content_crc) {
    throw InputError(
        StrCat(path, ": content checksum mismatch: the file is corrupt or was modified"));
  }
  const size_t bulk_bytes = total * (sizeof(MapPoint) + DescriptorBytes(skeleton.features)) +
                            observations * sizeof(uint32_t);
  paged.pages =
      std::make_shared<FilePageSource>(std::move(db), skeleton, static_cast<uint32_t>(total),
                                       std::max<uint32_t>(chunk_points, 1), bulk_bytes);
  return paged;
}

int SchemaVersionOf(const Map& map) { return map.metadata.lineage.empty() ? 1 : 2; }

MapInfo SummarizeMap(const Map& map, const std::string& path) {
  MapInfo info;
  info.path = path;
  info.schema_version = SchemaVersionOf(map);
  std::error_code error;
  info.file_bytes = path.empty() ? 0 : fs::file_size(path, error);
  if (error) info.file_bytes = 0;
  info.metadata = map.metadata;
  info.camera = map.camera;
  info.features = map.features;
  info.keyframes = map.keyframes.size();
  info.points = map.points.size();
  info.observations = map.observations.size();
  double error_sum = 0;
  for (const MapPoint& p : map.points) {
    info.point_extent.extend(p.position_in_map);
    error_sum += p.mean_reproj_error_px;
  }
  info.mean_reproj_error_px = map.points.empty() ? 0.0 : error_sum / map.points.size();
  for (const Keyframe& k : map.keyframes) info.keyframe_extent.extend(k.map_from_cam.translation);
  info.kernel_learned = map.kernel.metric.size() > 0;
  info.kernel = map.kernel;
  info.vocabulary_words = map.appearance.vocabulary.word_count();
  info.memory_bytes = LocalizationMap::MemoryBytesFor(map);
  return info;
}

VerifyReport VerifyMapFile(const std::string& path) {
  VerifyReport report;
  try {
    CheckFileExists(path);
    Database db = Database::OpenReadOnly(path);
    Statement integrity = db.Prepare("PRAGMA integrity_check(20)");
    while (integrity.Step()) {
      const std::string line = integrity.ColumnText(0);
      if (line != "ok") report.problems.push_back(StrCat(path, ": SQLite integrity check: ", line));
    }
    Statement foreign_keys = db.Prepare("PRAGMA foreign_key_check");
    if (foreign_keys.Step()) {
      report.problems.push_back(StrCat(path, ": dangling reference in table '",
                                       foreign_keys.ColumnText(0), "' row ",
                                       foreign_keys.ColumnInt64(1)));
    }
  } catch (const InputError& e) {
    report.problems.push_back(e.what());
    return report;
  }
  try {
    LoadMap(path);
  } catch (const InputError& e) {
    report.problems.push_back(e.what());
  }
  return report;
}

void SyncPath(const std::string& path, int flags) {
  const int fd = ::open(path.c_str(), flags);
  if (fd < 0) throw InputError(StrCat(path, ": cannot open to sync"));
  const int rc = ::fsync(fd);
  ::close(fd);
  if (rc != 0) throw InputError(StrCat(path, ": fsync failed"));
}

std::string TemporaryPathBeside(const std::string& path) {
  static std::atomic<int> counter{0};
  const fs::path target(path);
  const fs::path dir = target.has_parent_path() ? target.parent_path() : fs::path(".");
  return (dir / StrCat(".", target.filename().string(), ".tmp-", ::getpid(), "-", counter++))
      .string();
}

uint32_t Crc32(std::string_view bytes, uint32_t previous) {
  uLong crc = previous;
  const auto* p = reinterpret_cast<const Bytef*>(bytes.data());
  size_t left = bytes.size();
  while (left > 0) {  // zlib takes at most 4 GiB - 1 per call.
    const auto chunk = static_cast<uInt>(std::min<size_t>(left, 1u << 30));
    crc = crc32(crc, p, chunk);
    p += chunk;
    left -= chunk;
  }
  return static_cast<uint32_t>(crc);
}

}  // namespace visloc::mapstore
