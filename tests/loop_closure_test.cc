// Loop closure on the whole mapping square (the localization fixture's 5 fps rendering): the
// builder closes the loop either way, and only a closure whose correction is large re-adjusts
// every keyframe at once; small ones are left to local and final bundle adjustment.

#include <gtest/gtest.h>

#include "core/geometry/trajectory.h"
#include "dataset/dataset.h"
#include "dataset/tum.h"
#include "mapping/dataset_mapping.h"

namespace visloc {
namespace {

const std::string kData = VISLOC_LOCALIZATION_DATA;

struct LoopRun {
  mapping::MapBuildStats stats;
  double rmse_m = 0;  // Every frame's position against ground truth, map frame.
};

LoopRun BuildSquare(const mapping::MapBuilderOptions& options) {
  const Dataset dataset = ReadDataset(kData + "/map_square");
  const Trajectory truth = ReadTum(kData + "/map_square/groundtruth_map.tum");
  LoopRun run;
  Trajectory estimate;
  mapping::DatasetMappingOptions mapping_options;
  mapping_options.builder = options;
  mapping::BuildMap(dataset, mapping_options, {"loop", 0, "test", "test", ""}, &run.stats, &estimate);
  EXPECT_EQ(estimate.size(), truth.size());
  double sum_sq = 0;
  for (size_t i = 0; i < std::min(estimate.size(), truth.size()); ++i) {
    sum_sq += (estimate[i].pose.translation - truth[i].pose.translation).squaredNorm();
  }
  run.rmse_m = std::sqrt(sum_sq / std::max<size_t>(1, truth.size()));
  return run;
}

TEST(LoopClosureTest, OnlyLargeCorrectionsReadjustEveryKeyframe) {
  // The simulator's drift around the square is millimetres: below the default bounds.
  const LoopRun gated = BuildSquare(mapping::MapBuilderOptions{});
  mapping::MapBuilderOptions always;
  always.loop_closure.adjust_min_correction_m = 0.0;
  always.loop_closure.adjust_min_correction_deg = 0.0;
  const LoopRun adjusted = BuildSquare(always);
  std::printf("loop closures %d / %d, adjustments %d / %d, rmse %.2f / %.2f cm\n",
              gated.stats.loop_closures, adjusted.stats.loop_closures, gated.stats.loop_adjustments,
              adjusted.stats.loop_adjustments, 100 * gated.rmse_m, 100 * adjusted.rmse_m);
  EXPECT_GE(gated.stats.loop_closures, 1);
  EXPECT_EQ(gated.stats.loop_adjustments, 0);
  EXPECT_GE(adjusted.stats.loop_closures, 1);
  EXPECT_EQ(adjusted.stats.loop_adjustments, adjusted.stats.loop_closures);
  // Leaving small corrections to the final adjustment costs no accuracy.
  EXPECT_LT(gated.rmse_m, 0.01);
  EXPECT_LT(gated.rmse_m, adjusted.rmse_m + 0.002);
}

}  // namespace
}  // namespace visloc
