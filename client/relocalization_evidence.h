#pragma once
// The evidence behind relocalization's acceptance rule (relocalization_evidence.cc).

#include <cstddef>
#include <string>

#include "dataset/dataset.h"

namespace visloc::cli {

// Every frame of `dataset` alone against the map file at `map_path`, in process, both feature
// passes, every candidate verified and none refused: one TSV row per candidate (frame, pass,
// rank, keyframe, appearance score, matches, RANSAC inliers, verified, putatives, inliers, ratio,
// residual, inlier cells, significance, then the candidate's map_from_cam as tx ty tz qw qx qy
// qz), a frame with no candidate as one row of rank -1. Returns the rows written. Throws
// InputError when it cannot write.
size_t WriteRelocalizationEvidence(const std::string& map_path, const Dataset& dataset,
                                 const std::string& out_path);

}  // namespace visloc::cli
