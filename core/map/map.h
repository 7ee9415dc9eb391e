#pragma once
// The in-memory map model: what a map built from a stereo sequence contains, independent of how
// it is stored (mapstore owns the SQLite format) or used (LocalizationMap).
//
// Frames and units: the map frame is the left camera frame of the mapping sequence's first frame
// (product.md), metres. Keyframe poses are `map_from_cam` of the raw (unrectified) left camera.
// Pixels are in the map camera's raw, distorted image (Camera's convention).

#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "core/camera/camera.h"
#include "core/camera/disparity_correction.h"
#include "core/features/feature_types.h"
#include "core/geometry/rigid3.h"

namespace visloc {

// A stereo rig's calibration error as the map inherits it: the systematic position error (per
// axis, m) of a fix in the map, `floor_m` plus `drift_fraction` of the distance from the map's
// origin, in quadrature. A wrong baseline or focal length scales the whole map, and a distortion
// model's residual bends it; the images cannot show either (a map scaled by 0.3% is as
// consistent as the true one), so whoever calibrated the rig must say how well. Zero for a
// generated sequence, whose calibration is exact.
struct RigError {
  double floor_m = 0.0;
  double drift_fraction = 0.0;
  bool operator==(const RigError& other) const {
    return floor_m == other.floor_m && drift_fraction == other.drift_fraction;
  }
  bool operator!=(const RigError& other) const { return !(*this == other); }
};

// Where up is in a map: the direction opposite to gravity, in the map frame (the first left
// camera's optical frame, whose y axis points down only when that camera was held level), as
// its builder found it.
struct MapGravity {
  enum class Source {
    kImu,          // The recording's accelerometer, its motion's own acceleration taken off.
    kLevelRig,     // The rig's body declared level by the operator (a ground robot's base).
    kFloor,        // The mapped floor's plane, beneath the keyframes.
    kMotionPlane,  // The plane the keyframes moved in (a ground robot's), no floor seen.
    kImuAndFloor,  // The accelerometer's and the floor's, combined by their covariances.
  };
  Eigen::Vector3d up_in_map = Eigen::Vector3d::UnitZ();  // Unit.
  double sigma_deg = 0.0;  // One sigma of the direction's error, degrees.
  Source source = Source::kImu;
  bool operator==(const MapGravity& other) const {
    return up_in_map == other.up_in_map && sigma_deg == other.sigma_deg && source == other.source;
  }
  bool operator!=(const MapGravity& other) const { return !(*this == other); }
};
// "imu", "level_rig", "floor", "motion_plane", "imu_floor": how maps store and print it.
const char* GravitySourceName(MapGravity::Source source);
// The inverse; nullopt for any other text.
std::optional<MapGravity::Source> ParseGravitySource(const std::string& text);
// How far the map frame is from level (degrees): the angle between up and the map frame's -y,
// which is up when the first left camera was held level (OpenCV: y down).
double MapFrameTiltDeg(const MapGravity& gravity);

// The site's own frame a map is tied to (`visloc map align`): surveyed spots, a floor plan, a
// motion-capture or total-station frame; metric, z up by the site's convention.
struct SiteAlignment {
  Rigid3d site_from_map;
  int pairs = 0;                // Position pairs the fit used.
  double rms_m = 0.0;           // Their residual after it.
  double max_residual_m = 0.0;  // The largest.
  std::string reference;        // What the map was tied to, e.g. "pairs spots.csv".
  bool operator==(const SiteAlignment& other) const;
  bool operator!=(const SiteAlignment& other) const { return !(*this == other); }
};

// The map's level frame: z up (MapGravity::up_in_map), x the first camera's optical axis
// turned level (its heading), origin at the first camera. Identity rotation about up is kept
// as close to the camera's as levelling allows.
Rigid3d LevelFromMap(const MapGravity& gravity);

struct MapMetadata {
  std::string name;
  int64_t created_unix_s = 0;
  std::string source_dataset;  // Where the mapping sequence came from.
  std::string builder;         // Which program built it, e.g. "visloc 0.1.0 map build".
  // How the map came to be when it is more than one build: its sessions and merges, e.g.
  // "merge('lab' <- /data/mon; 'corridor' <- /data/tue)". Empty for a map of one build.
  std::string lineage;
  // The stereo rig's disparity correction the build took off its disparities, estimated by it
  // or given to it; none when it had neither (a run too short to estimate it from, a build that
  // trusts the rig's calibration, maps made before it was recorded). Sessions that extend or
  // update the map take it: they come from the same rig (its camera is checked).
  std::optional<DisparityCorrection> disparity_correction = std::nullopt;
  // The rig's calibration error, when its builder was told it; none: a real rig's, which the
  // localizer assumes (PoseTrackerOptions::rig_floor_m and rig_drift_fraction).
  std::optional<RigError> rig_error = std::nullopt;
  // The rectified stereo baseline of the rig the map was built with (m), which says how well
  // its stereo depths pinned its points (point_uncertainty.h); none in maps made before it was
  // recorded, whose fixes count the map's error without it.
  std::optional<double> stereo_baseline_m = std::nullopt;
  // Up, when the build could tell (MapGravity); none: it could not, or the map is older.
  std::optional<MapGravity> gravity = std::nullopt;
  // The site frame it is tied to, when an operator tied it (`visloc map align`).
  std::optional<SiteAlignment> site = std::nullopt;
};

// The frame a map speaks to robots, ROS and operators by default: the site it was tied to, else
// its level frame, else none (the map frame: it knows no up).
std::optional<Rigid3d> SiteFromMap(const MapMetadata& metadata);

struct Keyframe {
  int64_t timestamp_ns = 0;
  Rigid3d map_from_cam;
};

struct MapPoint {
  Eigen::Vector3d position_in_map = Eigen::Vector3d::Zero();
  uint32_t observation_count = 0;  // Keyframes that see the point (rows in observations).
  float mean_reproj_error_px = 0;  // Over those observations, after global bundle adjustment.
};

// Keyframe `keyframe` sees point `point` at `pixel`: the precomputed visibility.
struct Observation {
  uint32_t keyframe = 0;  // Index into Map::keyframes.
  uint32_t point = 0;     // Index into Map::points.
  Eigen::Vector2f pixel = Eigen::Vector2f::Zero();
};

// The learned visibility kernel of seed paper 000, eq. 7: for camera poses i and j with cue
// differences d_ij (one entry per cue), k_ij = exp(-|| metric * d_ij ||_2).
struct VisibilityKernel {
  std::vector<std::string> cues;               // e.g. {"translation_m", "view_direction"}
  Eigen::MatrixXd metric;                      // cues.size() x cues.size(); empty when not learned.
  int default_k = 10;                          // Nearest keyframes (paper: K = 10).
  double default_probability_threshold = 0.2;  // Paper: P_t = 0.2.
};

// A hierarchical k-means vocabulary for appearance retrieval (bag of words). Node rows are
// stored level by level below the root: level 1 holds `branching` rows, level 2 branching^2, ...
// The leaves (the last level) are the words.
struct Vocabulary {
  int branching = 0;
  int depth = 0;
  cv::Mat centroids;                // One row per node, the descriptors' type and width.
  std::vector<float> word_weights;  // IDF weight per word (leaf).
  bool empty() const { return centroids.empty(); }
  size_t word_count() const { return word_weights.size(); }
};

// A sparse bag-of-words vector: (word id, weight), sorted by word id.
using BowVector = std::vector<std::pair<uint32_t, float>>;

struct AppearanceIndex {
  Vocabulary vocabulary;
  std::vector<BowVector> keyframe_vectors;  // One per keyframe, or none.
};

struct Map {
  MapMetadata metadata;
  Camera camera;  // The map (left) camera.
  FeatureSettings features;
  std::vector<Keyframe> keyframes;
  std::vector<MapPoint> points;
  cv::Mat descriptors;  // points.size() rows of features.descriptor_dim, features.cv_type().
  std::vector<Observation> observations;  // Sorted by (keyframe, point).
  VisibilityKernel kernel;
  AppearanceIndex appearance;
};

// Checks what any consumer relies on: sizes agree, indices are in range, values are finite,
// quaternions unit, observations sorted and counted. Returns one message per problem (empty
// when sound); at most `max_problems` messages.
std::vector<std::string> FindMapProblems(const Map& map, size_t max_problems = 20);

// True when the two maps hold the same content, bit for bit.
bool MapsEqual(const Map& a, const Map& b);

// Editing a map's points (merge, update, adjustment). The kernel and appearance index are
// copied as they are: learn them again when the keyframes' views changed.
// `map` without the points flagged in `remove` (one flag per point); observations re-indexed.
Map WithoutPoints(const Map& map, const std::vector<bool>& remove);
// Sets every point's observation_count from the observations.
void CountObservations(Map* map);

}  // namespace visloc
