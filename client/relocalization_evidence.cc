// `visloc relocalize --map-file MAP.db --evidence OUT.tsv`: the evidence behind relocalization's
// acceptance rule, in process. Every frame of a dataset goes alone through the same query
// pipeline the Relocalize RPC uses, with both feature passes run and every candidate verified
// under no acceptance rule, so that any rule can be replayed on the rows afterwards
// (scripts/relocalization_rule.py): the rule is chosen on what the verifications measured, not
// tuned by rerunning the server.

#include "client/relocalization_evidence.h"

#include <fstream>
#include <limits>
#include <memory>

#include "core/localization/query_pipeline.h"
#include "core/util/check.h"
#include "mapstore/map_store.h"

namespace visloc::cli {
namespace {

// The session's options with the acceptance rule taken away: every candidate the retrieval
// offers is verified (no early stop), with RANSAC's own support lowered to what a minimal pose
// needs, so that the rows show how far wrong places get (the rule replays the session's
// min_matches and min_ransac_inliers on them).
LocalizerOptions WithoutAcceptanceRule() {
  LocalizerOptions options;
  RelocalizationOptions& r = options.relocalization;
  r.min_matches = 8;
  r.min_ransac_inliers = 6;
  r.min_verified_inliers = r.min_ransac_inliers;
  r.min_verified_inlier_ratio = 0.0;
  r.min_significance = 0.0;
  r.min_inlier_cells = 0;
  r.strong_inliers = std::numeric_limits<int>::max();
  r.strong_inlier_cells = 0;
  return options;
}

void WriteRow(std::ofstream& out, size_t frame, int64_t timestamp_ns, int pass, int rank,
              const RelocalizationCandidate& c) {
  const Eigen::Vector3d& t = c.map_from_cam.translation;
  const Eigen::Quaterniond& q = c.map_from_cam.rotation;
  out << frame << '\t' << timestamp_ns << '\t' << pass << '\t' << rank << '\t' << c.keyframe << '\t'
      << c.score << '\t' << c.matches << '\t' << c.ransac_inliers << '\t' << c.verified << '\t'
      << c.verified_putatives << '\t' << c.verified_inliers << '\t' << c.verified_inlier_ratio
      << '\t' << c.reproj_rmse_px << '\t' << c.inlier_cells << '\t' << c.significance << '\t'
      << t.x() << '\t' << t.y() << '\t' << t.z() << '\t' << q.w() << '\t' << q.x() << '\t' << q.y()
      << '\t' << q.z() << '\n';
}

// One row per candidate of `result`; a frame that retrieved none still gets one row, of rank -1
// (an empty candidate). Returns the rows written.
size_t WriteRows(std::ofstream& out, size_t frame, int64_t timestamp_ns, int pass,
                 const RelocalizationResult& result) {
  for (size_t rank = 0; rank < result.candidates.size(); ++rank) {
    WriteRow(out, frame, timestamp_ns, pass, static_cast<int>(rank), result.candidates[rank]);
  }
  if (!result.candidates.empty()) return result.candidates.size();
  WriteRow(out, frame, timestamp_ns, pass, -1, RelocalizationCandidate{});
  return 1;
}

}  // namespace

size_t WriteRelocalizationEvidence(const std::string& map_path, const Dataset& dataset,
                                   const std::string& out_path) {
  const auto map = std::make_shared<const LocalizationMap>(mapstore::LoadMap(map_path));
  const Camera& camera = dataset.left.camera;
  const QueryPipeline pipeline(map, camera, WithoutAcceptanceRule());
  std::ofstream out(out_path);
  if (!out) throw InputError("cannot write " + out_path);
  out << "frame\ttimestamp_ns\tpass\trank\tkeyframe\tscore\tmatches\transac_inliers\tverified\t"
         "putatives\tinliers\tinlier_ratio\treproj_rmse_px\tinlier_cells\tsignificance\t"
         "tx\tty\ttz\tqw\tqx\tqy\tqz\n";
  out.precision(9);
  size_t rows = 0;
  for (size_t i = 0; i < dataset.frames.size(); ++i) {
    const cv::Mat image =
        LoadGreyImage(dataset.frames[i].left_path, camera.width(), camera.height());
    const int64_t t = dataset.frames[i].timestamp_ns;
    rows += WriteRows(out, i, t, 1, pipeline.relocalizer().Relocalize(pipeline.Extract(image)));
    rows += WriteRows(out, i, t, 2,
                      pipeline.relocalizer().Relocalize(pipeline.ExtractForRelocalization(image)));
  }
  if (!out.flush()) throw InputError("cannot write " + out_path);
  return rows;
}

}  // namespace visloc::cli
