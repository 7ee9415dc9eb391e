// LoadMap and the readers of each table (map_file.h): every value checked as it is read, the
// structure and the content checksum after.

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <optional>
#include <utility>

#include "mapstore/map_file.h"
#include "mapstore/map_store.h"

namespace visloc::mapstore {
namespace fs = std::filesystem;
namespace internal {

void CheckFileExists(const std::string& path) {
  std::error_code error;
  if (!fs::is_regular_file(path, error)) throw InputError(StrCat(path, ": no such map file"));
  if (fs::file_size(path, error) == 0)
    throw InputError(StrCat(path, ": empty file, not a visloc map"));
}

// The meta table, key -> value (its key is the primary key: one row each).
using MetaRows = std::map<std::string, std::string>;

std::optional<std::string> Find(const MetaRows& rows, const std::string& key) {
  const auto it = rows.find(key);
  return it == rows.end() ? std::nullopt : std::optional<std::string>(it->second);
}

// Two finite numbers that meta holds both or neither of: `what` names them in errors.
std::optional<std::pair<double, double>> ReadNumberPair(const Database& db, const MetaRows& rows,
                                                        const std::string& key_a,
                                                        const std::string& key_b,
                                                        const std::string& what) {
  const std::optional<std::string> a = Find(rows, key_a);
  const std::optional<std::string> b = Find(rows, key_b);
  if (!a && !b) return std::nullopt;
  if (!a || !b) {
    throw InputError(StrCat(db.path(), ": meta has '", a ? key_a : key_b, "' without '",
                            a ? key_b : key_a, "'"));
  }
  const auto value_a = ParseDouble(*a), value_b = ParseDouble(*b);
  if (!value_a || !value_b || !std::isfinite(*value_a) || !std::isfinite(*value_b)) {
    throw InputError(StrCat(db.path(), ": malformed ", what, " in meta ('", *a, "', '", *b, "')"));
  }
  return std::make_pair(*value_a, *value_b);
}

// The meta keys 'disparity_offset_px' and 'right_camera_yaw_rad': both or neither, finite.
std::optional<DisparityCorrection> ReadDisparityCorrection(const Database& db,
                                                           const MetaRows& rows) {
  const auto pair = ReadNumberPair(db, rows, "disparity_offset_px", "right_camera_yaw_rad",
                                   "disparity correction");
  if (!pair) return std::nullopt;
  return DisparityCorrection{pair->first, pair->second};
}

// The meta keys 'rig_error_floor_m' and 'rig_error_drift_fraction': both or neither, finite, and
// neither negative.
std::optional<RigError> ReadRigError(const Database& db, const MetaRows& rows) {
  const auto pair = ReadNumberPair(db, rows, "rig_error_floor_m", "rig_error_drift_fraction",
                                   "rig calibration error");
  if (!pair) return std::nullopt;
  if (pair->first < 0 || pair->second < 0) {
    throw InputError(StrCat(db.path(), ": negative rig calibration error in meta (", pair->first,
                            " m, ", pair->second, ")"));
  }
  return RigError{pair->first, pair->second};
}

// The meta key 'stereo_baseline_m': a positive finite number, if present.
std::optional<double> ReadStereoBaseline(const Database& db, const MetaRows& rows) {
  const std::optional<std::string> text = Find(rows, "stereo_baseline_m");
  if (!text) return std::nullopt;
  const auto value = ParseDouble(*text);
  if (!value || !std::isfinite(*value) || *value <= 0) {
    throw InputError(StrCat(db.path(), ": malformed stereo baseline in meta ('", *text,
                            "'; a positive number of metres)"));
  }
  return *value;
}

// The meta keys 'gravity_up' ("x y z", a unit vector in the map frame), 'gravity_sigma_deg' (0
// or more) and 'gravity_source' (GravitySourceName): all three or none.
std::optional<MapGravity> ReadGravity(const Database& db, const MetaRows& rows) {
  const std::optional<std::string> up = Find(rows, "gravity_up");
  const std::optional<std::string> sigma = Find(rows, "gravity_sigma_deg");
  const std::optional<std::string> source = Find(rows, "gravity_source");
  if (!up && !sigma && !source) return std::nullopt;
  if (!up || !sigma || !source) {
    throw InputError(StrCat(db.path(), ": meta has part of the map's up direction (",
                            "'gravity_up', 'gravity_sigma_deg' and 'gravity_source' go together)"));
  }
  MapGravity gravity;
  const std::vector<std::string> parts = Split(*up, ' ');
  bool sound = parts.size() == 3;
  for (size_t i = 0; sound && i < 3; ++i) {
    const auto value = ParseDouble(parts[i]);
    sound = value && std::isfinite(*value);
    if (sound) gravity.up_in_map[static_cast<Eigen::Index>(i)] = *value;
  }
  const auto sigma_deg = ParseDouble(*sigma);
  const auto parsed_source = ParseGravitySource(*source);
  if (!sound || std::abs(gravity.up_in_map.norm() - 1) > 1e-6 || !sigma_deg ||
      !std::isfinite(*sigma_deg) || *sigma_deg < 0 || !parsed_source) {
    throw InputError(StrCat(db.path(), ": malformed up direction in meta ('", *up, "', '", *sigma,
                            "', '", *source, "')"));
  }
  gravity.sigma_deg = *sigma_deg;
  gravity.source = *parsed_source;
  return gravity;
}

// The meta keys 'site_from_map' ("tx ty tz qw qx qy qz", a unit quaternion), 'site_pairs' (3 or
// more), 'site_rms_m', 'site_max_residual_m' (not negative) and 'site_reference': all or none.
std::optional<SiteAlignment> ReadSiteAlignment(const Database& db, const MetaRows& rows) {
  const char* keys[] = {"site_from_map", "site_pairs", "site_rms_m", "site_max_residual_m",
                        "site_reference"};
  std::vector<std::optional<std::string>> values;
  for (const char* key : keys) values.push_back(Find(rows, key));
  const auto present = std::count_if(values.begin(), values.end(),
                                     [](const auto& value) { return value.has_value(); });
  if (present == 0) return std::nullopt;
  if (present != 5) {
    throw InputError(StrCat(db.path(),
                            ": meta has part of the map's site alignment ('site_from_map', "
                            "'site_pairs', 'site_rms_m', 'site_max_residual_m' and "
                            "'site_reference' go together)"));
  }
  const auto malformed = [&] {
    return InputError(StrCat(db.path(), ": malformed site alignment in meta ('", *values[0], "', '",
                             *values[1], "', '", *values[2], "', '", *values[3], "')"));
  };
  const std::vector<std::string> parts = SplitWhitespace(*values[0]);
  if (parts.size() != 7) throw malformed();
  double v[7];
  for (int i = 0; i < 7; ++i) {
    const auto value = ParseDouble(parts[i]);
    if (!value || !std::isfinite(*value)) throw malformed();
    v[i] = *value;
  }
  SiteAlignment site;
  site.site_from_map =
      Rigid3d(Eigen::Quaterniond(v[3], v[4], v[5], v[6]), Eigen::Vector3d(v[0], v[1], v[2]));
  const auto pairs = ParseInt64(*values[1]);
  const auto rms = ParseDouble(*values[2]);
  const auto max_residual = ParseDouble(*values[3]);
  if (std::abs(site.site_from_map.rotation.norm() - 1) > 1e-6 || !pairs || *pairs < 3 ||
      *pairs > (1 << 30) || !rms || !std::isfinite(*rms) || *rms < 0 || !max_residual ||
      !std::isfinite(*max_residual) || *max_residual < 0) {
    throw malformed();
  }
  site.pairs = static_cast<int>(*pairs);
  site.rms_m = *rms;
  site.max_residual_m = *max_residual;
  site.reference = *values[4];
  return site;
}

Meta ReadMeta(Database& db, Map* map) {
  if (!db.HasTable("meta")) throw InputError(db.path() + ": not a visloc map (no 'meta' table)");
  MetaRows rows;
  Statement query = db.Prepare("SELECT key, value FROM meta");
  while (query.Step()) rows.emplace(query.ColumnText(0), query.ColumnText(1));
  auto value = [&](const std::string& key) -> std::string {
    if (auto found = Find(rows, key)) return *found;
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
  map->metadata.lineage = Find(rows, "lineage").value_or("");              // Schema 2; optional.
  map->metadata.disparity_correction = ReadDisparityCorrection(db, rows);  // Schema 3; optional.
  map->metadata.rig_error = ReadRigError(db, rows);                          // Schema 4; optional.
  map->metadata.stereo_baseline_m = ReadStereoBaseline(db, rows);            // Schema 5; optional.
  map->metadata.gravity = ReadGravity(db, rows);                             // Schema 6; optional.
  map->metadata.site = ReadSiteAlignment(db, rows);                          // Schema 7; optional.
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

}  // namespace internal

using namespace internal;

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

}  // namespace visloc::mapstore
