// Loop closure on the whole mapping square (the localization fixture's 5 fps rendering): the
// builder closes the loop either way, and only a closure whose correction is large corrects
// every keyframe (through the pose graph); small ones are left to local and final bundle
// adjustment. The default
// build is the fixture's own (`visloc map build`: its JSON summary and trajectory), so only the
// always-adjust build runs here.

#include <gtest/gtest.h>

#include "core/geometry/trajectory.h"
#include "core/util/text_file.h"
#include "dataset/dataset.h"
#include "dataset/tum.h"
#include "mapping/dataset_mapping.h"
#include "tests/support/e2e.h"

namespace visloc {
namespace {

using testing::JsonNumber;

const std::string kData = VISLOC_LOCALIZATION_DATA;

struct LoopRun {
  int loop_closures = 0, loop_adjustments = 0;
  double rmse_m = 0;  // Every frame's position against ground truth, map frame.
};

double PositionRmse(const Trajectory& estimate) {
  const Trajectory truth = ReadTum(kData + "/map_square/groundtruth_map.tum");
  EXPECT_EQ(estimate.size(), truth.size());
  double sum_sq = 0;
  for (size_t i = 0; i < std::min(estimate.size(), truth.size()); ++i) {
    sum_sq += (estimate[i].pose.translation - truth[i].pose.translation).squaredNorm();
  }
  return std::sqrt(sum_sq / std::max<size_t>(1, truth.size()));
}

// The fixture's build, with the builder's default options.
LoopRun FixtureBuild() {
  const std::string json = ReadFileBytes(kData + "/map_build.json");
  LoopRun run;
  run.loop_closures = static_cast<int>(JsonNumber(json, "loop_closures"));
  run.loop_adjustments = static_cast<int>(JsonNumber(json, "loop_adjustments"));
  run.rmse_m = PositionRmse(ReadTum(kData + "/map_trajectory.tum"));
  return run;
}

LoopRun BuildSquare(const mapping::MapBuilderOptions& options) {
  const Dataset dataset = ReadDataset(kData + "/map_square");
  Trajectory estimate;
  mapping::DatasetMappingOptions mapping_options;
  mapping_options.builder = options;
  mapping::MapBuildStats stats;
  mapping::BuildMap(dataset, mapping_options, {"loop", 0, "test", "test", ""}, &stats, &estimate);
  LoopRun run;
  run.loop_closures = stats.loop_closures;
  run.loop_adjustments = stats.loop_adjustments;
  run.rmse_m = PositionRmse(estimate);
  return run;
}

TEST(LoopClosureTest, OnlyLargeCorrectionsReadjustEveryKeyframe) {
  // The simulator's drift around the square is millimetres: below the default bounds.
  const LoopRun gated = FixtureBuild();
  mapping::MapBuilderOptions always;
  always.loop_closure.adjust_min_correction_m = 0.0;
  always.loop_closure.adjust_min_correction_deg = 0.0;
  const LoopRun adjusted = BuildSquare(always);
  std::printf("loop closures %d / %d, adjustments %d / %d, rmse %.2f / %.2f cm\n",
              gated.loop_closures, adjusted.loop_closures, gated.loop_adjustments,
              adjusted.loop_adjustments, 100 * gated.rmse_m, 100 * adjusted.rmse_m);
  EXPECT_GE(gated.loop_closures, 1);
  EXPECT_EQ(gated.loop_adjustments, 0);
  EXPECT_GE(adjusted.loop_closures, 1);
  EXPECT_EQ(adjusted.loop_adjustments, adjusted.loop_closures);
  // Leaving small corrections to the final adjustment costs no accuracy.
  EXPECT_LT(gated.rmse_m, 0.01);
  EXPECT_LT(gated.rmse_m, adjusted.rmse_m + 0.002);
}

}  // namespace
}  // namespace visloc
