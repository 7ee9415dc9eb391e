// The content checksum (map_file.h) and CRC-32 itself (checksum.h).

#include <zlib.h>

#include <algorithm>

#include "mapstore/map_file.h"
#include "mapstore/map_store.h"

namespace visloc::mapstore {
namespace internal {
void ChecksumHead(const Map& map, Crc& crc) {
  crc.Text(map.metadata.name);
  crc.Pod(map.metadata.created_unix_s);
  crc.Text(map.metadata.source_dataset);
  crc.Text(map.metadata.builder);
  // Maps of one build checksum as before lineage existed.
  if (!map.metadata.lineage.empty()) crc.Text(map.metadata.lineage);
  // And as before the rig's correction was recorded, for maps without one.
  if (const auto& correction = map.metadata.disparity_correction) {
    crc.Pod(correction->offset_px);
    crc.Pod(correction->yaw_rad);
  }
  if (const auto& rig = map.metadata.rig_error) {
    crc.Pod(rig->floor_m);
    crc.Pod(rig->drift_fraction);
  }
  if (const auto& baseline_m = map.metadata.stereo_baseline_m) crc.Pod(*baseline_m);
  if (const auto& gravity = map.metadata.gravity) {
    for (int i = 0; i < 3; ++i) crc.Pod(gravity->up_in_map[i]);
    crc.Pod(gravity->sigma_deg);
    crc.Pod(static_cast<int32_t>(gravity->source));
  }
  if (const auto& site = map.metadata.site) {
    for (int i = 0; i < 3; ++i) crc.Pod(site->site_from_map.translation[i]);
    for (int i = 0; i < 4; ++i) crc.Pod(site->site_from_map.rotation.coeffs()[i]);
    crc.Pod(static_cast<int32_t>(site->pairs));
    crc.Pod(site->rms_m);
    crc.Pod(site->max_residual_m);
    crc.Text(site->reference);
  }
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

}  // namespace internal

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
