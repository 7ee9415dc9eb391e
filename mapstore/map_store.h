#pragma once
// The map file: one SQLite database per map (schema below, in map_store.cc and
// docs/map_format.md). This is the only place that knows the format.
//
// Durability: SaveMap writes a complete new file beside the target inside one transaction,
// syncs it, renames it over the target and syncs the folder, so a crash or kill at any moment
// leaves either the old map or the new one, never a half-written one. Reads open the file
// read-only; since files are only ever replaced by rename, never modified in place, any number
// of readers may load a map while it is being replaced (they keep the version they opened).
//
// Integrity: every load checks the schema, the structure (FindMapProblems) and a CRC-32 of the
// whole content stored at write time, so a flipped byte anywhere in the map's data is reported,
// not silently loaded.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "core/map/map.h"
#include "core/map/map_pages.h"

namespace visloc::mapstore {

// The schema this visloc writes and reads. Files with a higher version are refused with a
// message saying a newer visloc wrote them.
// 2: meta 'lineage' (merged and extended maps); 3: meta 'disparity_offset_px' and
// 'right_camera_yaw_rad' (the rig's disparity correction); 4: meta 'rig_error_floor_m' and
// 'rig_error_drift_fraction' (the rig's calibration error, when its builder was told it); 5:
// meta 'stereo_baseline_m' (the rig's baseline, which says how well its points are known); 6:
// meta 'gravity_up', 'gravity_sigma_deg' and 'gravity_source' (the map's up direction); 7: meta
// 'site_from_map', 'site_pairs', 'site_rms_m', 'site_max_residual_m' and 'site_reference' (the
// site frame `visloc map align` tied it to).
constexpr int kMapSchemaVersion = 7;

// The schema a map is written in: the lowest that holds what it has, so older visloc versions
// read every map they can: 1 without a lineage, a disparity correction or a rig error, 2 with a
// lineage, 3 with a disparity correction, 4 with a rig error, 5 with a stereo baseline, 6 with
// an up direction, 7 with a site alignment.
int SchemaVersionOf(const Map& map);

// The camera table's model column: "pinhole-radtan" (k1 k2 p1 p2 in the k1, k2, p1, p2
// columns) or "pinhole-equidistant" (fisheye; k1 k2 k3 k4 in the same four columns).
const char* CameraModelName(LensModel model);

struct SaveMapOptions {
  // SQLite page size: large pages load BLOB-heavy maps with fewer reads; small ones keep tiny
  // maps (fuzzing seeds, tests) small on disk. A power of two from 512 to 65536.
  int page_size_bytes = 65536;
};

// Throws CheckError for an inconsistent map (nothing is written), InputError when the file
// cannot be written (the previous file, if any, is left untouched).
void SaveMap(const Map& map, const std::string& path, const SaveMapOptions& options = {});

// Throws InputError "<path>: <problem>" naming the first problem: a missing, empty or
// non-SQLite file, a foreign database, missing tables, a newer schema, malformed rows,
// dangling references, non-finite values, or a checksum mismatch.
Map LoadMap(const std::string& path);

// A map opened for paged serving (LocalizationMap's paged constructor): `skeleton` holds
// everything but the points, descriptors and observations, which `pages` reads on demand from
// the file as it was when opened (files are replaced by rename, so a replacement does not
// disturb it; it holds the file open until the last page source is gone).
struct PagedMap {
  Map skeleton;
  std::shared_ptr<const MapPageSource> pages;
};

// Checks what LoadMap checks (schema, structure, the content checksum) streaming through the
// points and observations without holding them, so a map larger than memory opens in bounded
// memory (4 bytes per point for the observation counts). Throws InputError as LoadMap does.
PagedMap OpenPagedMap(const std::string& path);

struct MapInfo {
  std::string path;
  uint64_t file_bytes = 0;
  int schema_version = kMapSchemaVersion;
  MapMetadata metadata;
  Camera camera;
  FeatureSettings features;
  size_t keyframes = 0;
  size_t points = 0;
  size_t observations = 0;
  double mean_reproj_error_px = 0.0;    // Mean over points.
  Eigen::AlignedBox3d point_extent;     // Map frame, metres (empty for no points).
  Eigen::AlignedBox3d keyframe_extent;  // Keyframe camera centres.
  bool kernel_learned = false;
  VisibilityKernel kernel;
  size_t vocabulary_words = 0;
  size_t memory_bytes = 0;  // When loaded for localization (LocalizationMap::MemoryBytes).
};

MapInfo SummarizeMap(const Map& map, const std::string& path);

struct VerifyReport {
  std::vector<std::string> problems;  // Empty when the file is sound.
  bool ok() const { return problems.empty(); }
};

// Everything LoadMap checks, plus SQLite's page-level integrity check and foreign keys.
VerifyReport VerifyMapFile(const std::string& path);

}  // namespace visloc::mapstore
