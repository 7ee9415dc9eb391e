#include "mapping/site_alignment.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Eigenvalues>

#include "core/geometry/align.h"
#include "core/util/check.h"
#include "core/util/strings.h"
#include "mapping/gravity.h"

namespace visloc::mapping {
namespace {

Rigid3d Fit(const std::vector<PositionPair>& pairs, int left_out = -1) {
  std::vector<Eigen::Vector3d> in_map, in_site;
  for (int i = 0; i < static_cast<int>(pairs.size()); ++i) {
    if (i == left_out) continue;
    in_map.push_back(pairs[i].in_map);
    in_site.push_back(pairs[i].in_site);
  }
  return AlignRigid(in_map, in_site);
}

// The extent (m) of the map positions along their second principal direction: near zero for
// pairs on one line.
double SecondSpread(const std::vector<PositionPair>& pairs) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const PositionPair& p : pairs) mean += p.in_map;
  mean /= static_cast<double>(pairs.size());
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (const PositionPair& p : pairs) scatter += (p.in_map - mean) * (p.in_map - mean).transpose();
  const Eigen::Vector3d eigenvalues =
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(scatter / pairs.size()).eigenvalues();
  return 2 * std::sqrt(std::max(0.0, eigenvalues(1)));
}

}  // namespace

SiteAlignResult AlignToSite(const std::vector<PositionPair>& pairs,
                            const std::optional<MapGravity>& gravity, const std::string& reference,
                            const SiteAlignOptions& options) {
  SiteAlignResult result;
  const int n = static_cast<int>(pairs.size());
  if (n < options.min_pairs) {
    result.why_not = StrCat(n, " position pairs; a rigid fit needs ", options.min_pairs);
    return result;
  }
  const double spread_m = SecondSpread(pairs);
  if (spread_m < options.min_spread_m) {
    result.why_not = StrCat("the pairs lie on a line (", FormatFixed(spread_m * 100, 1),
                            " cm across it): the rotation about it is unknown");
    return result;
  }
  const Rigid3d site_from_map = Fit(pairs);
  double sum_sq = 0.0, max_residual = 0.0;
  for (const PositionPair& p : pairs) {
    const double residual = (p.in_site - site_from_map * p.in_map).norm();
    result.residuals_m.push_back(residual);
    sum_sq += residual * residual;
    max_residual = std::max(max_residual, residual);
  }
  // Each pair against the fit of the others: a wrong pair pulls the joint fit towards itself
  // and hides part of its error there, not here.
  int worst = -1;
  for (int i = 0; i < n; ++i) {
    double residual = result.residuals_m[i];
    if (n - 1 >= options.min_pairs) {
      residual = (pairs[i].in_site - Fit(pairs, i) * pairs[i].in_map).norm();
    }
    result.left_out_residuals_m.push_back(residual);
    if (worst < 0 || residual > result.left_out_residuals_m[worst]) worst = i;
  }
  if (gravity) {
    const Eigen::Vector3d up_in_site = site_from_map.rotation * gravity->up_in_map;
    result.site_z_from_up_deg =
        std::acos(std::clamp(up_in_site.normalized().z(), -1.0, 1.0)) * 180.0 / M_PI;
  }
  if (result.left_out_residuals_m[worst] > options.max_residual_m) {
    std::vector<double> others = result.left_out_residuals_m;
    others.erase(others.begin() + worst);
    std::nth_element(others.begin(), others.begin() + others.size() / 2, others.end());
    result.why_not = StrCat(
        "pair '", pairs[worst].name, "' is ", FormatFixed(result.left_out_residuals_m[worst], 3),
        " m from where the other pairs put it (over ", FormatFixed(options.max_residual_m, 3),
        " m; the others: median ", FormatFixed(others.empty() ? 0.0 : others[others.size() / 2], 3),
        " m): a wrong pair? Fix it or leave it out");
    return result;
  }
  SiteAlignment site;
  site.site_from_map = site_from_map;
  site.pairs = n;
  site.rms_m = std::sqrt(sum_sq / n);
  site.max_residual_m = max_residual;
  site.reference = reference;
  result.site = site;
  return result;
}

std::vector<PositionPair> PairsFromTrajectories(const Trajectory& map_from_cam,
                                                const Trajectory& site_from_cam,
                                                int64_t max_dt_ns) {
  // The reference by time, each estimate's neighbours found by bisection (a 20-minute run at
  // 20 Hz is 24,000 poses a side).
  Trajectory reference = site_from_cam;
  std::stable_sort(
      reference.begin(), reference.end(),
      [](const StampedPose& a, const StampedPose& b) { return a.timestamp_ns < b.timestamp_ns; });
  std::vector<PositionPair> pairs;
  for (const StampedPose& estimated : map_from_cam) {
    const int64_t t_ns = estimated.timestamp_ns;
    auto nearest =
        std::lower_bound(reference.begin(), reference.end(), t_ns,
                         [](const StampedPose& pose, int64_t t) { return pose.timestamp_ns < t; });
    if (nearest != reference.begin() &&
        (nearest == reference.end() ||
         t_ns - std::prev(nearest)->timestamp_ns < nearest->timestamp_ns - t_ns)) {
      --nearest;
    }
    if (nearest == reference.end() || std::llabs(nearest->timestamp_ns - t_ns) > max_dt_ns) {
      continue;
    }
    pairs.push_back({StrCat("t = ", FormatFixed(NsToSeconds(estimated.timestamp_ns), 3), " s"),
                     estimated.pose.translation, nearest->pose.translation});
  }
  return pairs;
}

std::optional<PlanFrame> PlanFrameOf(const Map& map, std::string* why_not) {
  if (const auto site_from_map = SiteFromMap(map.metadata)) {
    if (map.metadata.site) {
      return PlanFrame{*site_from_map, "site", "tied by " + map.metadata.site->reference};
    }
    return PlanFrame{*site_from_map, "level",
                     StrCat("level, up from ", GravitySourceName(map.metadata.gravity->source))};
  }
  // A drawing takes a floor too small to be the map's up: a few degrees off level still reads
  // as a floor plan, and the report says how level it is.
  GravityOptions to_draw;
  to_draw.max_floor_sigma_deg = kMaxDrawnFloorSigmaDeg;
  const GravityResult floor = GravityFromFloor(map, to_draw);
  if (!floor.gravity) {
    if (why_not) *why_not = "the map records no up and its floor does not tell: " + floor.why_not;
    return std::nullopt;
  }
  return PlanFrame{
      LevelFromMap(*floor.gravity), "floor",
      StrCat("level within ", FormatFixed(floor.gravity->sigma_deg, 1), " deg, up from the ",
             GravitySourceName(floor.gravity->source), " found now (the map records none)")};
}

}  // namespace visloc::mapping
