// SaveMap: a map written durably (map_store.h): a complete new file beside the target in one
// transaction, synced, renamed over the target, the folder synced.

#include <fcntl.h>

#include <cstdio>

#include <filesystem>

#include "mapstore/file_sync.h"
#include "mapstore/map_file.h"
#include "mapstore/map_store.h"

namespace visloc::mapstore {
namespace fs = std::filesystem;
namespace {

using namespace internal;

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
  if (!map.metadata.lineage.empty())
    insert.Bind(1, std::string("lineage")).Bind(2, map.metadata.lineage).Run();
  // 17 significant digits: the text reads back to the same doubles, which the checksum covers.
  auto insert_double = [&](const char* key, double value) {
    char text[32];
    std::snprintf(text, sizeof text, "%.17g", value);
    insert.Bind(1, std::string(key)).Bind(2, std::string(text)).Run();
  };
  if (const auto& correction = map.metadata.disparity_correction) {
    insert_double("disparity_offset_px", correction->offset_px);
    insert_double("right_camera_yaw_rad", correction->yaw_rad);
  }
  if (const auto& rig = map.metadata.rig_error) {
    insert_double("rig_error_floor_m", rig->floor_m);
    insert_double("rig_error_drift_fraction", rig->drift_fraction);
  }
  if (const auto& baseline_m = map.metadata.stereo_baseline_m) {
    insert_double("stereo_baseline_m", *baseline_m);
  }
  if (const auto& gravity = map.metadata.gravity) {
    char up[80];
    std::snprintf(up, sizeof up, "%.17g %.17g %.17g", gravity->up_in_map.x(),
                  gravity->up_in_map.y(), gravity->up_in_map.z());
    insert.Bind(1, std::string("gravity_up")).Bind(2, std::string(up)).Run();
    insert_double("gravity_sigma_deg", gravity->sigma_deg);
    insert.Bind(1, std::string("gravity_source"))
        .Bind(2, std::string(GravitySourceName(gravity->source)))
        .Run();
  }
  if (const auto& site = map.metadata.site) {
    const Rigid3d& pose = site->site_from_map;
    char text[200];
    std::snprintf(text, sizeof text, "%.17g %.17g %.17g %.17g %.17g %.17g %.17g",
                  pose.translation.x(), pose.translation.y(), pose.translation.z(),
                  pose.rotation.w(), pose.rotation.x(), pose.rotation.y(), pose.rotation.z());
    insert.Bind(1, std::string("site_from_map")).Bind(2, std::string(text)).Run();
    insert.Bind(1, std::string("site_pairs")).Bind(2, std::to_string(site->pairs)).Run();
    insert_double("site_rms_m", site->rms_m);
    insert_double("site_max_residual_m", site->max_residual_m);
    insert.Bind(1, std::string("site_reference")).Bind(2, site->reference).Run();
  }
}

void WriteCameraAndFeatures(Database& db, const Map& map) {
  const auto p = map.camera.Params();
  Statement camera = db.Prepare("INSERT INTO camera VALUES (0, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)");
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

}  // namespace visloc::mapstore
