#pragma once
// Finding the camera in the map from one image (seed paper 000, sec. 5.1), much faster than the
// paper's exhaustive keyframe matching: the image's bag of words ranks the map's keyframes
// (inverted index, so the cost grows with the keyframes that share words, not with the map),
// and the best candidates are verified geometrically, most similar first:
//   1. match the image's keypoints to the points the candidate keyframe sees (descriptors only),
//   2. PnP with RANSAC on those matches,
//   3. verify: predict the points visible from that pose, re-match them by projection in the
//      tracker's tight radius, and refine. Accept only with enough inliers at a high enough
//      inlier ratio, so an image from a place that is not in the map is refused rather than
//      forced onto the best candidate.
// A local search restricts the candidates to keyframes near a pose (fast relocalization around
// the last known pose when tracking is briefly lost).

#include <optional>
#include <vector>

#include "core/localization/pose_tracker.h"

namespace visloc {

struct RelocalizationOptions {
  int max_candidates = 4;  // Keyframes verified, best appearance score first.
  int min_matches = 20;    // Descriptor matches a candidate needs before RANSAC.
  int min_ransac_inliers = 15;
  // The acceptance rule: a verified candidate (re-matched by projection and refined) is taken
  // when all of these hold (Relocalizer::Accepts). Chosen on every frame of the real recordings
  // and generated walks, and on negatives (frames of other places), by
  // scripts/relocalization-rule.sh (docs/relocalization.md): the significance of the inliers
  // against chance separates true fixes (at least 97 on those frames) from the strongest wrong
  // place (22.5: a generated room like the map's, 84 inliers at a ratio of 0.7, which the ratio
  // gate of before took). The ratio gate (0.5) is off: on real frames a true fix re-matches many
  // predicted points to a wrong corner, and it refused fixes with 68-126 inliers.
  int min_verified_inliers = 30;  // After re-matching by projection: a session's strong fix.
  double min_verified_inlier_ratio = 0.0;
  // -log10 of the chance that a wrong pose gets as many inliers among its putatives
  // (ChanceInliersNegLog10), less log10 of max_candidates; 0 turns it off.
  double min_significance = 40.0;
  int min_inlier_cells = 0;  // Of PoseFix's coverage grid (48 cells); 0 turns it off.
  // Stop at the first accepted candidate this well supported: strong_inliers inliers in at least
  // strong_inlier_cells cells. A candidate whose inliers crowd part of the image can be biased
  // (a generated circle's frame: 232 inliers in 31 cells, 5.1 cm off, where the next candidate
  // had 374 in 45 cells and was right), so the search goes on and the best supported is kept.
  int strong_inliers = 80;
  int strong_inlier_cells = 36;
  DescriptorMatchOptions matching;  // Descriptor thresholds for step 1.
  // RANSAC's budget per candidate (it stops earlier once the inliers found make a better model
  // unlikely). Real images leave 15-20% of a candidate's descriptor matches correct (25-40 of
  // ~200): an all-inlier P3P sample is then 1 in 150-300 and 300 iterations miss it a third of
  // the time; rendered images match at 50% or more and stop after a few dozen.
  int ransac_iterations = 2000;
  void Check() const;
};

// Where to look: all keyframes, or those whose centres lie within radius_m of center_in_map.
struct RelocalizationScope {
  Eigen::Vector3d center_in_map = Eigen::Vector3d::Zero();
  double radius_m = 0.0;
};

struct RelocalizationCandidate {
  int keyframe = -1;
  float score = 0.0f;  // Appearance score in [0, 1].
  int matches = 0;
  int ransac_inliers = 0;
  // The verification's evidence (when RANSAC found a pose): the polished fix's success, its
  // putatives (tight re-matches), inliers and ratio, residual, image coverage, the significance
  // of its inlier count, and its pose.
  bool verified = false;
  int verified_putatives = 0;
  int verified_inliers = 0;
  double verified_inlier_ratio = 0.0;
  double reproj_rmse_px = 0.0;
  int inlier_cells = 0;
  double significance = 0.0;
  Rigid3d map_from_cam;
  bool accepted = false;
};

// Whether an accepted candidate is so well supported that the candidates after it are not
// verified (RelocalizationOptions::strong_inliers and strong_inlier_cells).
bool EndsSearch(const RelocalizationCandidate& candidate, const RelocalizationOptions& options);

// The chance model of a verification: a pose that is wrong re-matches each predicted point to
// whatever keypoint lies in the tight radius `search_radius_px` around its projection, at a
// place uniform over that disc, so each putative falls within the inlier threshold
// `inlier_px` by chance with p = (inlier_px / search_radius_px)^2. Returns -log10 of the
// binomial tail P[X >= inliers], X ~ B(putatives, p): 2 means one chance in 100 (the a contrario
// test of Moisan and Stival's ORSA, with the verification as the test).
double ChanceInliersNegLog10(int putatives, int inliers, double inlier_px, double search_radius_px);

// Where a relocalization's time went, ms. The candidate steps are summed over the candidates
// verified.
struct RelocalizationTimes {
  double features_ms = 0.0;      // Features, undistorted (RelocalizeImage only): both passes'.
  double retrieval_ms = 0.0;     // Bag of words, keyframe scores, ranking.
  double matching_ms = 0.0;      // Descriptor matching against each candidate's points.
  double ransac_ms = 0.0;        // PnP RANSAC on those matches.
  double verification_ms = 0.0;  // Re-matching by projection and refinement (Polish).
  RelocalizationTimes& operator+=(const RelocalizationTimes& other);
};

struct RelocalizationResult {
  bool success = false;
  PoseFix fix;  // The verified pose and its statistics (when success).
  int keyframe = -1;
  std::vector<RelocalizationCandidate> candidates;  // As tried, best appearance first.
  double ms = 0.0;
  RelocalizationTimes times;
  // Feature passes it took (QueryPipeline::RelocalizeImage): 1 with the tracking features or
  // the full ones alone, 2 when the tracking features verified nothing and the full ones ran.
  int feature_passes = 1;
};

class Relocalizer {
 public:
  // `tracker` provides the map, the camera and the verification; it must outlive this.
  Relocalizer(const PoseTracker& tracker, const RelocalizationOptions& options);

  RelocalizationResult Relocalize(const QueryFrame& frame,
                                  const std::optional<RelocalizationScope>& scope = {}) const;

 private:
  void Verify(const QueryFrame& frame, RelocalizationCandidate* candidate, PoseFix* fix,
              RelocalizationTimes* times) const;
  // The acceptance rule (RelocalizationOptions) on a verified candidate's evidence.
  bool Accepts(const RelocalizationCandidate& candidate) const;

  const PoseTracker& tracker_;
  RelocalizationOptions options_;
};

}  // namespace visloc
