#include "mapstore/map_store.h"

#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <filesystem>

#include "core/map/localization_map.h"
#include "mapstore/file_sync.h"
#include "mapstore/map_file.h"

// The map file's code, by what it does: map_write.cc (SaveMap), map_read.cc (LoadMap and the
// table readers), paged_map.cc (OpenPagedMap), map_checksum.cc (the content checksum);
// map_file.h holds what they share. Here: summaries, verification and file helpers.

namespace visloc::mapstore {
namespace fs = std::filesystem;

const char* CameraModelName(LensModel model) {
  return model == LensModel::kEquidistant ? "pinhole-equidistant" : "pinhole-radtan";
}

int SchemaVersionOf(const Map& map) {
  if (map.metadata.site) return 7;
  if (map.metadata.gravity) return 6;
  if (map.metadata.stereo_baseline_m) return 5;
  if (map.metadata.rig_error) return 4;
  if (map.metadata.disparity_correction) return 3;
  return map.metadata.lineage.empty() ? 1 : 2;
}

namespace internal {

std::string JoinCues(const std::vector<std::string>& cues) {
  std::string out;
  for (const std::string& cue : cues) out += (out.empty() ? "" : ",") + cue;
  return out;
}

size_t DescriptorBytes(const FeatureSettings& features) {
  return features.descriptor_dim * (features.descriptor_type == DescriptorType::kFloat32 ? 4 : 1);
}

}  // namespace internal

using namespace internal;

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

}  // namespace visloc::mapstore
