#include "core/localization/relocalizer.h"

#include <algorithm>
#include <cmath>

#include "core/map/vocabulary.h"
#include "core/util/check.h"
#include "core/util/timer.h"

namespace visloc {

void RelocalizationOptions::Check() const {
  VISLOC_CHECK(max_candidates >= 1 && min_matches >= 4 && min_ransac_inliers >= 4 &&
                   min_verified_inliers >= min_ransac_inliers && ransac_iterations >= 1,
               "relocalization thresholds");
  VISLOC_CHECK(min_verified_inlier_ratio >= 0 && min_verified_inlier_ratio <= 1,
               "relocalization inlier ratio ", min_verified_inlier_ratio);
  constexpr int kCells = PoseFix::kCoverageCols * PoseFix::kCoverageRows;
  VISLOC_CHECK(min_significance >= 0 && min_inlier_cells >= 0 && min_inlier_cells <= kCells &&
                   strong_inlier_cells >= 0 && strong_inlier_cells <= kCells,
               "relocalization significance ", min_significance, ", cells ", min_inlier_cells,
               ", strong cells ", strong_inlier_cells);
  matching.Check();
}

double ChanceInliersNegLog10(int putatives, int inliers, double inlier_px,
                             double search_radius_px) {
  VISLOC_CHECK(putatives >= 0 && inliers >= 0 && inliers <= putatives && inlier_px > 0 &&
                   search_radius_px > 0,
               "chance model: ", inliers, " of ", putatives, ", ", inlier_px, " px in ",
               search_radius_px, " px");
  if (inliers == 0) return 0.0;
  const double p = std::min(1.0, std::pow(inlier_px / search_radius_px, 2));
  if (p >= 1.0) return 0.0;
  // log P[X = j], summed from j = inliers up with log-sum-exp (the terms span hundreds of
  // decades for a few hundred putatives).
  const auto log_term = [&](int j) {
    return std::lgamma(putatives + 1.0) - std::lgamma(j + 1.0) - std::lgamma(putatives - j + 1.0) +
           j * std::log(p) + (putatives - j) * std::log1p(-p);
  };
  const double first = log_term(inliers);
  double sum = 0.0;
  for (int j = inliers; j <= putatives; ++j) {
    const double ratio = std::exp(log_term(j) - first);
    sum += ratio;
    if (ratio < 1e-17 * sum) break;  // Past the mode the terms only shrink.
  }
  return -(first + std::log(sum)) / std::log(10.0);
}

RelocalizationTimes& RelocalizationTimes::operator+=(const RelocalizationTimes& other) {
  features_ms += other.features_ms;
  retrieval_ms += other.retrieval_ms;
  matching_ms += other.matching_ms;
  ransac_ms += other.ransac_ms;
  verification_ms += other.verification_ms;
  return *this;
}

Relocalizer::Relocalizer(const PoseTracker& tracker, const RelocalizationOptions& options)
    : tracker_(tracker), options_(options) {
  options_.Check();
  VISLOC_CHECK(tracker.map().has_appearance_index(),
               "the map has no appearance index (vocabulary and keyframe vectors)");
}

void Relocalizer::Verify(const QueryFrame& frame, RelocalizationCandidate* candidate, PoseFix* fix,
                         RelocalizationTimes* times) const {
  Timer timer;
  const LocalizationMap& map = tracker_.map();
  const auto visible = map.VisiblePoints(candidate->keyframe);
  const std::vector<uint32_t> points(visible.begin(), visible.end());
  const PointView map_points = map.Points(points);
  const std::vector<PointMatch> matches =
      MatchByDescriptor(map_points, points, frame, options_.matching);
  times->matching_ms += timer.ElapsedMs();
  candidate->matches = static_cast<int>(matches.size());
  if (candidate->matches < options_.min_matches) return;
  PnpRansacOptions ransac = tracker_.options().ransac;
  ransac.min_inliers = options_.min_ransac_inliers;
  ransac.max_iterations = options_.ransac_iterations;
  ransac.seed = static_cast<uint64_t>(candidate->keyframe) + 1;
  timer.Restart();
  const PnpResult pnp = SolvePnpRansac(tracker_.Observations(map_points, frame, matches), ransac);
  times->ransac_ms += timer.ElapsedMs();
  candidate->ransac_inliers = pnp.stats.inliers;
  if (!pnp.success) return;
  timer.Restart();
  *fix = tracker_.Polish(frame, pnp.cam_from_world);
  times->verification_ms += timer.ElapsedMs();
  fix->ransac_iterations = pnp.stats.iterations;
  candidate->verified = fix->success;
  candidate->verified_putatives = fix->putatives;
  candidate->verified_inliers = fix->inliers;
  candidate->verified_inlier_ratio = fix->inlier_ratio;
  candidate->reproj_rmse_px = fix->reproj_rmse_px;
  candidate->inlier_cells = fix->inlier_cells;
  const PoseTrackerOptions& tracking = tracker_.options();
  candidate->significance =
      ChanceInliersNegLog10(fix->putatives, fix->inliers, tracking.ransac.max_error_px,
                            tracking.refine_radius_px) -
      std::log10(static_cast<double>(options_.max_candidates));
  candidate->map_from_cam = fix->cam_from_map.Inverse();
  candidate->accepted = Accepts(*candidate);
}

bool EndsSearch(const RelocalizationCandidate& candidate, const RelocalizationOptions& options) {
  return candidate.accepted && candidate.verified_inliers >= options.strong_inliers &&
         candidate.inlier_cells >= options.strong_inlier_cells;
}

bool Relocalizer::Accepts(const RelocalizationCandidate& candidate) const {
  return candidate.verified && candidate.verified_inliers >= options_.min_verified_inliers &&
         candidate.verified_inlier_ratio >= options_.min_verified_inlier_ratio &&
         candidate.significance >= options_.min_significance &&
         candidate.inlier_cells >= options_.min_inlier_cells;
}

RelocalizationResult Relocalizer::Relocalize(
    const QueryFrame& frame, const std::optional<RelocalizationScope>& scope) const {
  Timer timer;
  RelocalizationResult result;
  const LocalizationMap& map = tracker_.map();
  const BowVector query = ComputeBow(map.map().appearance.vocabulary, frame.features().descriptors);
  const std::vector<float> scores = map.ScoreKeyframes(query);
  std::vector<int> ranked;
  for (size_t k = 0; k < scores.size(); ++k) {
    const bool in_scope =
        !scope || (map.keyframe_centers()[k] - scope->center_in_map).norm() <= scope->radius_m;
    if (scores[k] > 0 && in_scope) ranked.push_back(static_cast<int>(k));
  }
  const size_t keep = std::min<size_t>(options_.max_candidates, ranked.size());
  std::partial_sort(ranked.begin(), ranked.begin() + keep, ranked.end(), [&](int a, int b) {
    return scores[a] > scores[b] || (scores[a] == scores[b] && a < b);
  });
  ranked.resize(keep);
  result.times.retrieval_ms = timer.ElapsedMs();
  for (int keyframe : ranked) {
    RelocalizationCandidate candidate;
    candidate.keyframe = keyframe;
    candidate.score = scores[keyframe];
    PoseFix fix;
    Verify(frame, &candidate, &fix, &result.times);
    result.candidates.push_back(candidate);
    if (candidate.accepted && (!result.success || fix.inliers > result.fix.inliers)) {
      result.success = true;
      result.fix = fix;
      result.keyframe = keyframe;
      if (EndsSearch(candidate, options_)) break;
    }
  }
  result.ms = timer.ElapsedMs();
  return result;
}

}  // namespace visloc
