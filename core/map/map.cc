#include "core/map/map.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "core/util/check.h"

namespace visloc {

namespace {

bool Finite(const Eigen::Vector3d& v) { return v.allFinite(); }

bool PoseIsSound(const Rigid3d& pose) {
  return Finite(pose.translation) && pose.rotation.coeffs().allFinite() &&
         std::abs(pose.rotation.norm() - 1.0) < 1e-6;
}

class ProblemList {
 public:
  explicit ProblemList(size_t max) : max_(max) {}
  template <typename... Args>
  void Add(Args&&... args) {
    if (problems_.size() < max_) problems_.push_back(StrCat(std::forward<Args>(args)...));
  }
  bool full() const { return problems_.size() >= max_; }
  std::vector<std::string> Take() { return std::move(problems_); }

 private:
  size_t max_;
  std::vector<std::string> problems_;
};

void CheckDescriptors(const Map& map, ProblemList& problems) {
  const FeatureSettings& f = map.features;
  if (f.kind.empty()) problems.Add("feature kind is empty");
  if (f.descriptor_dim <= 0) problems.Add("descriptor dimension ", f.descriptor_dim);
  if (map.descriptors.rows != static_cast<int>(map.points.size())) {
    problems.Add(map.points.size(), " points but ", map.descriptors.rows, " descriptors");
  } else if (!map.points.empty() &&
             (map.descriptors.cols != f.descriptor_dim || map.descriptors.type() != f.cv_type())) {
    problems.Add("descriptors are ", map.descriptors.cols, " wide of type ", map.descriptors.type(),
                 ", settings say ", f.descriptor_dim, " of type ", f.cv_type());
  } else if (f.descriptor_type == DescriptorType::kFloat32 && !map.descriptors.empty() &&
             !cv::checkRange(map.descriptors)) {
    problems.Add("descriptors contain non-finite values");
  }
}

void CheckObservations(const Map& map, ProblemList& problems) {
  std::vector<uint32_t> counted(map.points.size(), 0);
  for (size_t i = 0; i < map.observations.size() && !problems.full(); ++i) {
    const Observation& o = map.observations[i];
    if (o.keyframe >= map.keyframes.size() || o.point >= map.points.size()) {
      problems.Add("observation ", i, " refers to keyframe ", o.keyframe, " and point ", o.point,
                   " but the map has ", map.keyframes.size(), " keyframes and ", map.points.size(),
                   " points");
      continue;
    }
    if (!o.pixel.allFinite()) problems.Add("observation ", i, " has a non-finite pixel");
    if (i > 0) {
      const Observation& p = map.observations[i - 1];
      if (std::make_pair(p.keyframe, p.point) >= std::make_pair(o.keyframe, o.point)) {
        problems.Add("observations are not sorted by (keyframe, point) at ", i);
      }
    }
    ++counted[o.point];
  }
  for (size_t j = 0; j < map.points.size() && !problems.full(); ++j) {
    if (counted[j] != map.points[j].observation_count) {
      problems.Add("point ", j, " claims ", map.points[j].observation_count,
                   " observations but has ", counted[j]);
    }
  }
}

void CheckAppearance(const Map& map, ProblemList& problems) {
  const Vocabulary& v = map.appearance.vocabulary;
  if (!v.empty()) {
    size_t nodes = 0, level = 1;
    for (int d = 0; d < v.depth; ++d) nodes += (level *= v.branching);
    if (v.branching < 2 || v.depth < 1 || static_cast<size_t>(v.centroids.rows) != nodes ||
        v.word_count() != level) {
      problems.Add("vocabulary of branching ", v.branching, " and depth ", v.depth, " has ",
                   v.centroids.rows, " nodes and ", v.word_count(), " word weights");
    }
  }
  const auto& vectors = map.appearance.keyframe_vectors;
  if (!vectors.empty() && vectors.size() != map.keyframes.size()) {
    problems.Add(vectors.size(), " appearance vectors for ", map.keyframes.size(), " keyframes");
  }
  for (size_t k = 0; k < vectors.size() && !problems.full(); ++k) {
    for (size_t w = 0; w < vectors[k].size(); ++w) {
      if (vectors[k][w].first >= v.word_count() || !std::isfinite(vectors[k][w].second) ||
          (w > 0 && vectors[k][w - 1].first >= vectors[k][w].first)) {
        problems.Add("appearance vector of keyframe ", k, " has a bad entry at ", w);
        break;
      }
    }
  }
}

}  // namespace

const char* GravitySourceName(MapGravity::Source source) {
  switch (source) {
    case MapGravity::Source::kImu:
      return "imu";
    case MapGravity::Source::kLevelRig:
      return "level_rig";
    case MapGravity::Source::kFloor:
      return "floor";
    case MapGravity::Source::kMotionPlane:
      return "motion_plane";
    case MapGravity::Source::kImuAndFloor:
      return "imu_floor";
  }
  return "unknown";
}

bool SiteAlignment::operator==(const SiteAlignment& other) const {
  return site_from_map.translation == other.site_from_map.translation &&
         site_from_map.rotation.coeffs() == other.site_from_map.rotation.coeffs() &&
         pairs == other.pairs && rms_m == other.rms_m && max_residual_m == other.max_residual_m &&
         reference == other.reference;
}

Rigid3d LevelFromMap(const MapGravity& gravity) {
  const Eigen::Vector3d up = gravity.up_in_map.normalized();
  // x: the map's z (the first camera's optical axis) made level; a camera looking straight up
  // or down takes its x instead.
  Eigen::Vector3d forward = Eigen::Vector3d::UnitZ() - up.z() * up;
  if (forward.norm() < 1e-6) forward = Eigen::Vector3d::UnitX() - up.x() * up;
  forward.normalize();
  Eigen::Matrix3d level_from_map;
  level_from_map.row(0) = forward.transpose();
  level_from_map.row(1) = up.cross(forward).transpose();
  level_from_map.row(2) = up.transpose();
  return Rigid3d(Eigen::Quaterniond(level_from_map).normalized(), Eigen::Vector3d::Zero());
}

std::optional<Rigid3d> SiteFromMap(const MapMetadata& metadata) {
  if (metadata.site) return metadata.site->site_from_map;
  if (metadata.gravity) return LevelFromMap(*metadata.gravity);
  return std::nullopt;
}

double MapFrameTiltDeg(const MapGravity& gravity) {
  const double cosine = std::clamp(-gravity.up_in_map.normalized().y(), -1.0, 1.0);
  return std::acos(cosine) * 180.0 / M_PI;
}

std::optional<MapGravity::Source> ParseGravitySource(const std::string& text) {
  for (const MapGravity::Source source :
       {MapGravity::Source::kImu, MapGravity::Source::kLevelRig, MapGravity::Source::kFloor,
        MapGravity::Source::kMotionPlane, MapGravity::Source::kImuAndFloor}) {
    if (text == GravitySourceName(source)) return source;
  }
  return std::nullopt;
}

std::vector<std::string> FindMapProblems(const Map& map, size_t max_problems) {
  ProblemList problems(max_problems);
  if (map.metadata.name.empty()) problems.Add("map name is empty");
  if (map.camera.width() <= 0) problems.Add("map camera is not set");
  if (const auto& correction = map.metadata.disparity_correction;
      correction && !(std::isfinite(correction->offset_px) && std::isfinite(correction->yaw_rad))) {
    problems.Add("the rig's disparity correction is not finite");
  }
  if (const auto& rig = map.metadata.rig_error;
      rig && !(rig->floor_m >= 0 && std::isfinite(rig->floor_m) && rig->drift_fraction >= 0 &&
               std::isfinite(rig->drift_fraction))) {
    problems.Add("the rig's calibration error is negative or not finite");
  }
  if (const auto& baseline_m = map.metadata.stereo_baseline_m;
      baseline_m && !(*baseline_m > 0 && std::isfinite(*baseline_m))) {
    problems.Add("the rig's stereo baseline is not a positive number (", *baseline_m, " m)");
  }
  if (const auto& gravity = map.metadata.gravity;
      gravity && !(Finite(gravity->up_in_map) && std::abs(gravity->up_in_map.norm() - 1) < 1e-6 &&
                   gravity->sigma_deg >= 0 && std::isfinite(gravity->sigma_deg))) {
    problems.Add("the map's up direction is not a unit vector with a sigma of 0 or more degrees");
  }
  if (const auto& site = map.metadata.site;
      site && !(PoseIsSound(site->site_from_map) && site->pairs >= 3 && site->rms_m >= 0 &&
                std::isfinite(site->rms_m) && site->max_residual_m >= site->rms_m &&
                std::isfinite(site->max_residual_m))) {
    problems.Add("the map's site alignment is not sound (a pose, 3 or more pairs, residuals)");
  }
  for (size_t i = 0; i < map.keyframes.size() && !problems.full(); ++i) {
    if (!PoseIsSound(map.keyframes[i].map_from_cam)) {
      problems.Add("keyframe ", i, " has a non-finite pose or a non-unit quaternion");
    }
  }
  for (size_t j = 0; j < map.points.size() && !problems.full(); ++j) {
    if (!Finite(map.points[j].position_in_map) ||
        !std::isfinite(map.points[j].mean_reproj_error_px)) {
      problems.Add("point ", j, " has a non-finite position or error");
    }
  }
  CheckDescriptors(map, problems);
  CheckObservations(map, problems);
  const VisibilityKernel& kernel = map.kernel;
  const auto cues = static_cast<Eigen::Index>(kernel.cues.size());
  if (kernel.metric.size() > 0 && (kernel.metric.rows() != cues || kernel.metric.cols() != cues ||
                                   !kernel.metric.allFinite())) {
    problems.Add("visibility kernel metric is ", kernel.metric.rows(), "x", kernel.metric.cols(),
                 " for ", cues, " cues");
  }
  if (kernel.default_k < 1 || !(kernel.default_probability_threshold >= 0.0 &&
                                kernel.default_probability_threshold <= 1.0)) {
    problems.Add("visibility defaults K = ", kernel.default_k,
                 ", P_t = ", kernel.default_probability_threshold);
  }
  CheckAppearance(map, problems);
  return problems.Take();
}

namespace {

bool SameMat(const cv::Mat& a, const cv::Mat& b) {
  if (a.empty() && b.empty()) return true;
  if (a.size() != b.size() || a.type() != b.type()) return false;
  for (int r = 0; r < a.rows; ++r) {
    if (std::memcmp(a.ptr(r), b.ptr(r), a.cols * a.elemSize()) != 0) return false;
  }
  return true;
}

bool SamePose(const Rigid3d& a, const Rigid3d& b) {
  return a.translation == b.translation && a.rotation.coeffs() == b.rotation.coeffs();
}

}  // namespace

bool MapsEqual(const Map& a, const Map& b) {
  if (a.metadata.name != b.metadata.name ||
      a.metadata.created_unix_s != b.metadata.created_unix_s ||
      a.metadata.source_dataset != b.metadata.source_dataset ||
      a.metadata.builder != b.metadata.builder || a.metadata.lineage != b.metadata.lineage ||
      a.metadata.disparity_correction != b.metadata.disparity_correction ||
      a.metadata.rig_error != b.metadata.rig_error ||
      a.metadata.stereo_baseline_m != b.metadata.stereo_baseline_m ||
      a.metadata.gravity != b.metadata.gravity || a.metadata.site != b.metadata.site) {
    return false;
  }
  if (a.camera.width() != b.camera.width() || a.camera.height() != b.camera.height() ||
      a.camera.Params() != b.camera.Params()) {
    return false;
  }
  if (a.features.kind != b.features.kind ||
      a.features.descriptor_type != b.features.descriptor_type ||
      a.features.descriptor_dim != b.features.descriptor_dim ||
      a.features.params != b.features.params) {
    return false;
  }
  if (a.keyframes.size() != b.keyframes.size() || a.points.size() != b.points.size() ||
      a.observations.size() != b.observations.size()) {
    return false;
  }
  for (size_t i = 0; i < a.keyframes.size(); ++i) {
    if (a.keyframes[i].timestamp_ns != b.keyframes[i].timestamp_ns ||
        !SamePose(a.keyframes[i].map_from_cam, b.keyframes[i].map_from_cam)) {
      return false;
    }
  }
  for (size_t j = 0; j < a.points.size(); ++j) {
    const MapPoint &p = a.points[j], &q = b.points[j];
    if (p.position_in_map != q.position_in_map || p.observation_count != q.observation_count ||
        p.mean_reproj_error_px != q.mean_reproj_error_px) {
      return false;
    }
  }
  for (size_t i = 0; i < a.observations.size(); ++i) {
    const Observation &o = a.observations[i], &p = b.observations[i];
    if (o.keyframe != p.keyframe || o.point != p.point || o.pixel != p.pixel) return false;
  }
  const VisibilityKernel &ka = a.kernel, &kb = b.kernel;
  if (ka.cues != kb.cues || ka.metric.rows() != kb.metric.rows() ||
      ka.metric.cols() != kb.metric.cols() || ka.metric != kb.metric ||
      ka.default_k != kb.default_k ||
      ka.default_probability_threshold != kb.default_probability_threshold) {
    return false;
  }
  const Vocabulary &va = a.appearance.vocabulary, &vb = b.appearance.vocabulary;
  return SameMat(a.descriptors, b.descriptors) && va.branching == vb.branching &&
         va.depth == vb.depth && SameMat(va.centroids, vb.centroids) &&
         va.word_weights == vb.word_weights &&
         a.appearance.keyframe_vectors == b.appearance.keyframe_vectors;
}

Map WithoutPoints(const Map& map, const std::vector<bool>& remove) {
  VISLOC_CHECK(remove.size() == map.points.size(), "one flag per point");
  Map kept = map;
  kept.points.clear();
  kept.descriptors = cv::Mat(0, map.descriptors.cols, map.descriptors.type());
  kept.observations.clear();
  std::vector<int> new_index(map.points.size(), -1);
  for (size_t p = 0; p < map.points.size(); ++p) {
    if (remove[p]) continue;
    new_index[p] = static_cast<int>(kept.points.size());
    kept.points.push_back(map.points[p]);
    kept.descriptors.push_back(map.descriptors.row(static_cast<int>(p)));
  }
  for (const Observation& o : map.observations) {
    if (new_index[o.point] >= 0) {
      kept.observations.push_back({o.keyframe, static_cast<uint32_t>(new_index[o.point]), o.pixel});
    }
  }
  return kept;
}

void CountObservations(Map* map) {
  for (MapPoint& p : map->points) p.observation_count = 0;
  for (const Observation& o : map->observations) ++map->points[o.point].observation_count;
}

}  // namespace visloc
