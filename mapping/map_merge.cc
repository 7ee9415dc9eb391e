#include "mapping/map_merge.h"

#include <algorithm>
#include <cmath>

#include "core/features/descriptor.h"
#include "core/features/descriptor_matching.h"
#include "core/geometry/align.h"
#include "core/util/check.h"
#include "core/util/random.h"
#include "core/util/strings.h"
#include "mapping/point_grid.h"

namespace visloc::mapping {
namespace {

// Matched positions: B's point and A's point of one descriptor match.
struct PointPair {
  int b = 0;
  int a = 0;
  Eigen::Vector3d in_b = Eigen::Vector3d::Zero();
  Eigen::Vector3d in_a = Eigen::Vector3d::Zero();
};

void RequireSameSensor(const Map& a, const Map& b) {
  if (!SameCamera(a.camera, b.camera)) {
    throw InputError(StrCat("the maps' cameras differ (", ToString(a.camera), " and ",
                            ToString(b.camera), "): maps of one camera can be merged"));
  }
  if (a.features.kind != b.features.kind ||
      a.features.descriptor_dim != b.features.descriptor_dim ||
      a.features.descriptor_type != b.features.descriptor_type) {
    throw InputError(StrCat("the maps' features differ (", a.features.kind, " and ",
                            b.features.kind, "): their descriptors cannot be matched"));
  }
}

std::vector<int> Inliers(const std::vector<PointPair>& pairs, const Rigid3d& a_from_b,
                         double max_distance_m) {
  std::vector<int> inliers;
  for (size_t i = 0; i < pairs.size(); ++i) {
    if ((a_from_b * pairs[i].in_b - pairs[i].in_a).norm() <= max_distance_m) {
      inliers.push_back(static_cast<int>(i));
    }
  }
  return inliers;
}

Rigid3d Fit(const std::vector<PointPair>& pairs, const std::vector<int>& chosen) {
  std::vector<Eigen::Vector3d> source, target;
  for (int i : chosen) {
    source.push_back(pairs[i].in_b);
    target.push_back(pairs[i].in_a);
  }
  return AlignRigid(source, target);
}

// Two least-squares refits, each on the inliers of the last fit.
std::vector<int> Refit(const std::vector<PointPair>& pairs, double max_distance_m,
                       std::vector<int> inliers, Rigid3d* a_from_b) {
  for (int refit = 0; refit < 2 && inliers.size() >= 3; ++refit) {
    *a_from_b = Fit(pairs, inliers);
    inliers = Inliers(pairs, *a_from_b, max_distance_m);
  }
  return inliers;
}

// RANSAC over minimal samples of three pairs, then two refits on the inliers.
std::vector<int> VerifiedInliers(const std::vector<PointPair>& pairs, const MergeOptions& options,
                                 Rigid3d* a_from_b) {
  Rng rng(options.seed);
  std::vector<int> best;
  const int n = static_cast<int>(pairs.size());
  for (int iteration = 0; iteration < options.ransac_iterations && n >= 3; ++iteration) {
    const int i = rng.UniformInt(0, n - 1), j = rng.UniformInt(0, n - 1),
              k = rng.UniformInt(0, n - 1);
    if (i == j || j == k || i == k) continue;
    // A thin triangle leaves the rotation about its long side undetermined.
    const Eigen::Vector3d ab = pairs[j].in_b - pairs[i].in_b, ac = pairs[k].in_b - pairs[i].in_b;
    if (ab.cross(ac).norm() < 0.01) continue;  // m^2: sides of ~10 cm at least.
    const Rigid3d candidate = Fit(pairs, {i, j, k});
    std::vector<int> inliers = Inliers(pairs, candidate, options.inlier_distance_m);
    if (inliers.size() > best.size()) {
      best = std::move(inliers);
      *a_from_b = candidate;
    }
  }
  return Refit(pairs, options.inlier_distance_m, std::move(best), a_from_b);
}

// B placed near its place in A by a guess: each B point paired with the A point within the
// inlier distance whose descriptor is closest (and passes the match threshold), each A point
// with one B point at most. No search over the whole maps: the cost grows with B's points.
std::vector<PointPair> PairsNear(const Map& a, const Map& b, const Rigid3d& a_from_b,
                                 const MergeOptions& options) {
  PointGrid grid(options.inlier_distance_m);
  for (size_t p = 0; p < a.points.size(); ++p)
    grid.Add(a.points[p].position_in_map, static_cast<int>(p));
  const float max_distance = options.match.MaxDistance(a.features.descriptor_type);
  // Per A point: the closest B descriptor so far, and that B point.
  std::vector<std::pair<float, int>> best_of_a(a.points.size(), {max_distance, -1});
  for (size_t p = 0; p < b.points.size(); ++p) {
    const Eigen::Vector3d in_a = a_from_b * b.points[p].position_in_map;
    int best = -1;
    float best_distance = max_distance;
    grid.ForEachWithin(in_a, options.inlier_distance_m, [&](int candidate, const Eigen::Vector3d&) {
      const float d =
          DescriptorDistance(b.descriptors, static_cast<int>(p), a.descriptors, candidate);
      if (d <= best_distance) {
        best = candidate;
        best_distance = d;
      }
    });
    if (best >= 0 && best_distance <= best_of_a[best].first)
      best_of_a[best] = {best_distance, static_cast<int>(p)};
  }
  std::vector<PointPair> pairs;
  for (size_t q = 0; q < a.points.size(); ++q) {
    const int p = best_of_a[q].second;
    if (p >= 0)
      pairs.push_back(
          {p, static_cast<int>(q), b.points[p].position_in_map, a.points[q].position_in_map});
  }
  return pairs;
}

// B points that the descriptor matching did not pair (it keeps mutual nearest neighbours over
// the whole maps, so a texture repeated elsewhere hides a duplicate): fused with the nearest A
// point within the fuse distance whose descriptor passes the match threshold, each A point
// taking one B point at most.
void FuseNearby(const Map& a, const Map& b, const Rigid3d& a_from_b, const MergeOptions& options,
                std::vector<int>* point_of_b, int* fused) {
  if (!(options.fuse_distance_m > 0)) return;
  PointGrid grid(options.fuse_distance_m);
  for (size_t p = 0; p < a.points.size(); ++p)
    grid.Add(a.points[p].position_in_map, static_cast<int>(p));
  std::vector<bool> taken(a.points.size(), false);
  for (int target : *point_of_b) {
    if (target >= 0) taken[target] = true;
  }
  const float max_distance = options.match.MaxDistance(a.features.descriptor_type);
  for (size_t p = 0; p < b.points.size(); ++p) {
    if ((*point_of_b)[p] >= 0) continue;
    const Eigen::Vector3d in_a = a_from_b * b.points[p].position_in_map;
    int best = -1;
    double best_m = options.fuse_distance_m;
    grid.ForEachWithin(in_a, options.fuse_distance_m, [&](int candidate, const Eigen::Vector3d& x) {
      const double d = (x - in_a).norm();
      if (taken[candidate] || d > best_m) return;
      if (DescriptorDistance(b.descriptors, static_cast<int>(p), a.descriptors, candidate) >
          max_distance)
        return;
      best = candidate;
      best_m = d;
    });
    if (best < 0) continue;
    (*point_of_b)[p] = best;
    taken[best] = true;
    ++*fused;
  }
}

// Every keyframe's descriptors: those of the points it observes.
std::vector<cv::Mat> KeyframeDescriptors(const Map& map) {
  std::vector<cv::Mat> per_keyframe(map.keyframes.size());
  for (const Observation& o : map.observations)
    per_keyframe[o.keyframe].push_back(map.descriptors.row(o.point));
  for (cv::Mat& d : per_keyframe) {
    if (d.empty()) d = cv::Mat(0, map.descriptors.cols, map.descriptors.type());
  }
  return per_keyframe;
}

}  // namespace

bool SameCamera(const Camera& a, const Camera& b) {
  const auto pa = a.Params(), pb = b.Params();
  bool same = a.width() == b.width() && a.height() == b.height() &&
              a.lens().model == b.lens().model && pa.size() == pb.size();
  for (size_t i = 0; same && i < pa.size(); ++i) {
    same &= std::abs(pa[i] - pb[i]) <= 1e-6 * (1 + std::abs(pa[i]));
  }
  return same;
}

void MergeOptions::Check() const {
  match.Check();
  if (!(inlier_distance_m > 0 && inlier_distance_m < 10))
    throw CheckError("inlier distance must be 0 to 10 m");
  if (ransac_iterations < 1) throw CheckError("RANSAC needs at least one iteration");
  if (min_inliers < 3) throw CheckError("at least 3 inliers are needed to fix an alignment");
  if (!(min_inlier_ratio >= 0 && min_inlier_ratio <= 1))
    throw CheckError("the inlier ratio is 0 to 1");
  if (!(fuse_distance_m >= 0)) throw CheckError("the fuse distance must not be negative");
}

std::string MergedLineage(const MapMetadata& a, const MapMetadata& b, const std::string& verb) {
  auto of = [](const MapMetadata& m) {
    return m.lineage.empty() ? StrCat("'", m.name, "' <- ", m.source_dataset) : m.lineage;
  };
  return StrCat(verb, "(", of(a), "; ", of(b), ")");
}

namespace {

struct Registration {
  Rigid3d a_from_b;
  std::vector<PointPair> pairs;
  std::vector<int> inliers;  // Into pairs.
};

Registration Register(const Map& a, const Map& b, const MergeOptions& options,
                      const std::optional<Rigid3d>& a_from_b_guess, MergeStats* stats) {
  options.Check();
  RequireSameSensor(a, b);
  *stats = MergeStats{};
  stats->keyframes_a = static_cast<int>(a.keyframes.size());
  stats->keyframes_b = static_cast<int>(b.keyframes.size());
  stats->points_a = static_cast<int>(a.points.size());
  stats->points_b = static_cast<int>(b.points.size());
  stats->from_guess = a_from_b_guess.has_value();

  std::vector<PointPair> pairs;
  Rigid3d a_from_b;
  std::vector<int> inliers;
  if (a_from_b_guess) {
    pairs = PairsNear(a, b, *a_from_b_guess, options);
    a_from_b = *a_from_b_guess;
    inliers = Refit(pairs, options.inlier_distance_m,
                    Inliers(pairs, a_from_b, options.inlier_distance_m), &a_from_b);
  } else {
    for (const auto& [row_b, row_a] :
         MatchMutualNearest(b.descriptors, a.descriptors, options.match)) {
      pairs.push_back(
          {row_b, row_a, b.points[row_b].position_in_map, a.points[row_a].position_in_map});
    }
    inliers = VerifiedInliers(pairs, options, &a_from_b);
  }
  stats->matches = static_cast<int>(pairs.size());
  stats->inliers = static_cast<int>(inliers.size());
  const double ratio = pairs.empty() ? 0.0 : static_cast<double>(inliers.size()) / pairs.size();
  if (a_from_b_guess && stats->inliers < options.min_inliers) {
    throw InputError(StrCat("B's points do not meet A's where B was placed: ", stats->matches,
                            " of B's points have a look-alike in A within ",
                            FormatFixed(100 * options.inlier_distance_m, 1), " cm, ",
                            stats->inliers, " of them agree on one rigid alignment; a merge needs ",
                            options.min_inliers));
  }
  if (!a_from_b_guess &&
      (stats->inliers < options.min_inliers || ratio < options.min_inlier_ratio)) {
    throw InputError(
        StrCat("the maps have no verified overlap: ", stats->matches,
               " descriptor matches between their points, of which ", stats->inliers, " (",
               static_cast<int>(100 * ratio), "%) agree on one rigid alignment; ", "a merge needs ",
               options.min_inliers, " and ", static_cast<int>(100 * options.min_inlier_ratio),
               "%. Maps of different places are not merged"));
  }
  double sum_sq = 0.0;
  for (int i : inliers) sum_sq += (a_from_b * pairs[i].in_b - pairs[i].in_a).squaredNorm();
  stats->inlier_rmse_m = std::sqrt(sum_sq / inliers.size());
  stats->a_from_b = a_from_b;
  return {a_from_b, std::move(pairs), std::move(inliers)};
}

}  // namespace

Rigid3d RegisterMaps(const Map& a, const Map& b, const MergeOptions& options, MergeStats* stats,
                     const std::optional<Rigid3d>& a_from_b_guess) {
  return Register(a, b, options, a_from_b_guess, stats).a_from_b;
}

std::vector<bool> KeyframesHeldInMergeAdjustment(const Map& merged, size_t keyframes_a) {
  std::vector<bool> seen_by_b(merged.points.size(), false);
  for (const Observation& o : merged.observations) {
    if (o.keyframe >= keyframes_a) seen_by_b[o.point] = true;
  }
  std::vector<bool> hold(merged.keyframes.size(), false);
  std::fill(hold.begin(), hold.begin() + keyframes_a, true);
  for (const Observation& o : merged.observations) {
    if (o.keyframe < keyframes_a && seen_by_b[o.point]) hold[o.keyframe] = false;
  }
  hold[0] = true;
  return hold;
}

Map MergeMaps(const Map& a, const Map& b, const MergeOptions& options, MergeStats* stats,
              const std::optional<Rigid3d>& a_from_b_guess) {
  const Registration registration = Register(a, b, options, a_from_b_guess, stats);
  const Rigid3d& a_from_b = registration.a_from_b;
  const std::vector<PointPair>& pairs = registration.pairs;
  const std::vector<int>& inliers = registration.inliers;

  Map merged;
  merged.metadata = a.metadata;
  merged.metadata.lineage = MergedLineage(a.metadata, b.metadata);
  // The rig's correction, calibration error and baseline (one camera, checked): A's, else B's
  // build recorded.
  if (!merged.metadata.disparity_correction) {
    merged.metadata.disparity_correction = b.metadata.disparity_correction;
  }
  if (!merged.metadata.rig_error) merged.metadata.rig_error = b.metadata.rig_error;
  if (!merged.metadata.stereo_baseline_m) {
    merged.metadata.stereo_baseline_m = b.metadata.stereo_baseline_m;
  }
  // Up: the better known of the two, b's turned into a's frame.
  if (auto b_gravity = b.metadata.gravity;
      b_gravity &&
      (!merged.metadata.gravity || b_gravity->sigma_deg < merged.metadata.gravity->sigma_deg)) {
    b_gravity->up_in_map = (a_from_b.rotation * b_gravity->up_in_map).normalized();
    merged.metadata.gravity = b_gravity;
  }
  // The site: A's, else B's through B's frame in A's.
  if (!merged.metadata.site && b.metadata.site) {
    merged.metadata.site = b.metadata.site;
    merged.metadata.site->site_from_map = b.metadata.site->site_from_map * a_from_b.Inverse();
  }
  merged.camera = a.camera;
  merged.features = a.features;
  merged.keyframes = a.keyframes;
  for (const Keyframe& k : b.keyframes)
    merged.keyframes.push_back({k.timestamp_ns, a_from_b * k.map_from_cam});
  merged.points = a.points;
  merged.descriptors = a.descriptors.clone();
  // Where each B point goes: a fused A point, or a new point after A's.
  std::vector<int> point_of_b(b.points.size(), -1);
  for (int i : inliers) {
    if ((a_from_b * pairs[i].in_b - pairs[i].in_a).norm() <= options.fuse_distance_m) {
      point_of_b[pairs[i].b] = pairs[i].a;
      ++stats->fused_points;
    }
  }
  FuseNearby(a, b, a_from_b, options, &point_of_b, &stats->fused_points);
  // A fused point was measured by both maps' stereo: it starts halfway between the two (and the
  // adjustment's prior holds it near there), not where A alone put it. On the square + circle
  // merge this took B's farthest keyframe from 1.03 to 0.99 cm, A's from 1.14 to 1.06 cm.
  for (size_t p = 0; p < b.points.size(); ++p) {
    if (point_of_b[p] < 0) continue;
    Eigen::Vector3d& position = merged.points[point_of_b[p]].position_in_map;
    position = 0.5 * (position + a_from_b * b.points[p].position_in_map);
  }
  for (size_t p = 0; p < b.points.size(); ++p) {
    if (point_of_b[p] >= 0) continue;
    point_of_b[p] = static_cast<int>(merged.points.size());
    MapPoint point = b.points[p];
    point.position_in_map = a_from_b * point.position_in_map;
    merged.points.push_back(point);
    merged.descriptors.push_back(b.descriptors.row(static_cast<int>(p)));
    ++stats->added_points;
  }
  merged.observations = a.observations;
  const uint32_t first_b_keyframe = static_cast<uint32_t>(a.keyframes.size());
  for (const Observation& o : b.observations) {
    merged.observations.push_back(
        {first_b_keyframe + o.keyframe, static_cast<uint32_t>(point_of_b[o.point]), o.pixel});
  }
  std::sort(merged.observations.begin(), merged.observations.end(),
            [](const Observation& x, const Observation& y) {
              return x.keyframe != y.keyframe ? x.keyframe < y.keyframe : x.point < y.point;
            });
  CountObservations(&merged);
  if (!options.skip_adjustment) {
    stats->adjustment = AdjustMap(
        &merged, KeyframesHeldInMergeAdjustment(merged, a.keyframes.size()), options.adjustment);
  }

  merged.kernel = LearnVisibilityKernel(merged, options.visibility, &stats->visibility);
  merged.appearance.vocabulary = TrainVocabulary(merged.descriptors, options.vocabulary);
  IndexKeyframes(KeyframeDescriptors(merged), &merged.appearance.vocabulary,
                 &merged.appearance.keyframe_vectors);
  const std::vector<std::string> problems = FindMapProblems(merged);
  VISLOC_CHECK(problems.empty(), "the merged map is inconsistent: ", problems.front());
  return merged;
}

}  // namespace visloc::mapping
