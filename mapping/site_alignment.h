#pragma once
// Ties a map to its site's own frame (`visloc map align`): pairs of positions, each a point in
// the map and the same point in the site (a robot localized at a surveyed spot; one run's poses
// beside a reference trajectory with the same stamps: a total station's, motion capture's,
// RTK-GNSS's), solved as the rigid transform site_from_map (Umeyama, no scale: a stereo map is
// metric). Every pair is checked against the fit of the others (leave one out): a pair that
// disagrees with the rest by more than SiteAlignOptions::max_residual_m is named and the fit
// refused, with the evidence.
//
// Frames: map (the map's), site (the reference's). Units: metres, degrees.

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "core/geometry/trajectory.h"
#include "core/map/map.h"

namespace visloc::mapping {

struct PositionPair {
  std::string name;  // How the operator finds it again: "spots.csv line 4", "t = 12.350 s".
  Eigen::Vector3d in_map = Eigen::Vector3d::Zero();
  Eigen::Vector3d in_site = Eigen::Vector3d::Zero();
};

struct SiteAlignOptions {
  // A pair farther than this from where the other pairs put it is refused as a wrong pair.
  double max_residual_m = 0.10;
  int min_pairs = 3;
  // Pairs spanning less than this (m, the second principal direction's extent) leave the
  // rotation about their line unknown.
  double min_spread_m = 0.2;
};

struct SiteAlignResult {
  std::optional<SiteAlignment> site;
  // Each pair's distance from the fit of all (m), and from the fit of the others (m).
  std::vector<double> residuals_m, left_out_residuals_m;
  // The angle between the site's z and the map's up (deg), when the map knows up: how level
  // the site frame is by the map's own gravity.
  std::optional<double> site_z_from_up_deg;
  std::string why_not;  // When there is no site: the reason, naming the pair at fault.
};

SiteAlignResult AlignToSite(const std::vector<PositionPair>& pairs,
                            const std::optional<MapGravity>& gravity, const std::string& reference,
                            const SiteAlignOptions& options = {});

// Pairs from a trajectory of the map frame (a localization run's TUM output) beside a reference
// trajectory of the site frame: each estimated pose with a reference pose within `max_dt_ns`.
std::vector<PositionPair> PairsFromTrajectories(const Trajectory& map_from_cam,
                                                const Trajectory& site_from_cam,
                                                int64_t max_dt_ns = 10'000'000);

// The level frame a map is seen from above in (the operator's page, `map localizability`): its
// site frame (map.h SiteFromMap); for a map that records no up, levelled on its floor now (not
// stored, and taken at up to kMaxDrawnFloorSigmaDeg); none when the floor does not tell either
// (`why_not` says why).
constexpr double kMaxDrawnFloorSigmaDeg = 8.0;
struct PlanFrame {
  Rigid3d site_from_map;
  std::string name;  // "site" (tied by map align), "level" (the map's up) or "floor" (found now).
  std::string how;   // For reports, e.g. "level, up from imu".
};
std::optional<PlanFrame> PlanFrameOf(const Map& map, std::string* why_not = nullptr);

}  // namespace visloc::mapping
