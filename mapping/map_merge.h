#pragma once
// Two maps of overlapping places become one, in the first map's frame (`visloc map merge`).
//
//   overlap:   B's points matched to A's by descriptor alone (mutual nearest neighbours with the
//              ratio test), then verified geometrically: RANSAC over 3-point rigid alignments of
//              the matched 3D positions (stereo maps share metric scale, so no scale), refit on
//              the inliers. Too few inliers, or too small a share of the matches, is "no overlap":
//              the merge is refused, never made wrongly (maps of different rooms with the same
//              kind of texture match descriptors by chance, but not in a consistent geometry).
//              When B is already placed roughly in A (a guess: a new session whose images were
//              localized in A, session_registration.h), each B point is paired instead with the
//              A point near it whose descriptor is closest, and the guess refit on the pairs
//              that agree: no search over the whole maps, so a session joins a big map as fast
//              as a small one.
//   fusion:    B's keyframes moved into A's frame; a B point that matched an A point and lies
//              within `fuse_distance_m` of it after the alignment becomes that point (its
//              observations join A's, A's descriptor is kept, the position is the mean of the
//              two maps' stereo estimates), as does one whose nearest A point within that distance
//              has a descriptor close enough (the mutual matching misses duplicates of repeated
//              textures); the rest of B's points are added.
//   adjustment: a bundle adjustment over the merged map (map_adjustment.h): B's keyframes and
//              A's that share a point with B are free, A's first keyframe (the frame A's robots
//              localize in) and A's beyond the seam are held, and every point is held near its
//              own map's stereo position by a prior (the map keeps mono observations only).
//              Where B sees all of A, that is a global adjustment; a small session merged into
//              a big map adjusts only the region it saw. A's seam keyframes are weighted this
//              way rather than held: held, they pulled B onto A's own errors; freed without the
//              priors, the mono observations loosened both maps (docs/maps.md has the figures).
//   models:    the visibility kernel is learned again over all keyframes, the relocalization
//              vocabulary trained on all points, and every keyframe indexed by the points it
//              observes.

#include <optional>
#include <string>
#include <vector>

#include "core/features/feature_types.h"
#include "core/map/map.h"
#include "mapping/map_adjustment.h"
#include "mapping/visibility_learning.h"
#include "mapping/vocabulary_builder.h"

namespace visloc::mapping {

struct MergeOptions {
  DescriptorMatchOptions match;     // Between the maps' point descriptors.
  double inlier_distance_m = 0.05;  // A matched pair agrees with an alignment within this.
  int ransac_iterations = 2000;
  int min_inliers = 40;             // Fewer: no overlap.
  double min_inlier_ratio = 0.15;   // Of the descriptor matches; fewer: no overlap.
  double fuse_distance_m = 0.03;    // A matched B point this close to its A point is fused.
  uint64_t seed = 1;
  bool skip_adjustment = false;  // No bundle adjustment after the fusion.
  MapAdjustmentOptions adjustment;
  VisibilityLearningOptions visibility;
  VocabularyOptions vocabulary;
  // Throws CheckError naming the first bad value (the match options' too).
  void Check() const;
};

struct MergeStats {
  bool from_guess = false;  // Registered near a guess (the pairs below are by position).
  int matches = 0;  // Descriptor matches between the maps' points (or pairs near the guess).
  int inliers = 0;             // Of those, consistent with the alignment.
  double inlier_rmse_m = 0.0;  // Of the inliers after the refit.
  Rigid3d a_from_b;            // B's map frame in A's.
  int keyframes_a = 0, keyframes_b = 0;
  int points_a = 0, points_b = 0;
  int fused_points = 0;  // B points that became A points.
  int added_points = 0;  // B points added.
  MapAdjustmentStats adjustment;
  VisibilityLearningStats visibility;
};

// Throws InputError naming the reason when the maps cannot be merged: different cameras or
// features, or no verified overlap (the evidence in the message). `a_from_b_guess`: B's frame in
// A's as far as it is known (within a few centimetres), refined with the points near it; without
// it, the overlap is searched for by descriptor over the whole maps.
Map MergeMaps(const Map& a, const Map& b, const MergeOptions& options, MergeStats* stats,
              const std::optional<Rigid3d>& a_from_b_guess = std::nullopt);

// The overlap alone: B's map frame in A's (a_from_b), verified as MergeMaps does; the same
// errors. Fills the registration part of `stats`.
Rigid3d RegisterMaps(const Map& a, const Map& b, const MergeOptions& options, MergeStats* stats,
                     const std::optional<Rigid3d>& a_from_b_guess = std::nullopt);

// Whether two maps' (or a map's and a session's) cameras are one: size, lens model and every
// parameter within a part in a million. Maps of different cameras are not merged.
bool SameCamera(const Camera& a, const Camera& b);

// The keyframes the merge's adjustment holds, for a merged map whose first `keyframes_a` are
// A's: A's first (the frame) and A's that share no point with B (beyond the seam; they anchor
// the points they share with the seam's keyframes).
std::vector<bool> KeyframesHeldInMergeAdjustment(const Map& merged, size_t keyframes_a);

// The lineage line of a merge, for MapMetadata::lineage: "<verb>(<A's lineage>; <B's lineage>)",
// where a map without lineage stands for itself as "'name' <- source". `verb` is "merge" for two
// maps, "extend" for a map and a new session.
std::string MergedLineage(const MapMetadata& a, const MapMetadata& b,
                          const std::string& verb = "merge");

}  // namespace visloc::mapping
