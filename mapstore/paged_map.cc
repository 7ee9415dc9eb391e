// OpenPagedMap: what LoadMap checks, streamed through the points and observations without
// holding them, and a page source that reads them by id afterwards (map_store.h).

#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <mutex>

#include "core/map/localization_map.h"
#include "mapstore/map_file.h"
#include "mapstore/map_store.h"

namespace visloc::mapstore {
namespace {

using namespace internal;

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

}  // namespace visloc::mapstore
