#include "core/estimators/inlier_counter.h"

#include <gtest/gtest.h>

#include "core/util/random.h"

namespace visloc {
namespace {

// Observations of points around a camera: noisy, some far off, some behind it (negative depth
// under the poses below), half with a right observation, some with a fisheye's pixel scale.
std::vector<PoseObservation> Scattered(int count, Rng& rng) {
  std::vector<PoseObservation> observations;
  for (int i = 0; i < count; ++i) {
    PoseObservation o;
    o.point_in_world = Eigen::Vector3d(rng.Uniform(-3, 3), rng.Uniform(-2, 2), rng.Uniform(-1, 8));
    o.normalized = Eigen::Vector2d(rng.Uniform(-1, 1), rng.Uniform(-0.8, 0.8));
    o.has_right = rng.Uniform01() < 0.5;
    o.right_x_normalized = o.normalized.x() - rng.Uniform(0.0, 0.1);
    o.pixel_scale = rng.Uniform01() < 0.8 ? 1.0 : rng.Uniform(0.5, 1.0);
    observations.push_back(o);
  }
  return observations;
}

int CountOneByOne(const std::vector<PoseObservation>& observations, const Rigid3d& pose,
                  const PoseRefineOptions& options, double max_error_px) {
  const PoseProjector projector(pose, options);
  int count = 0;
  for (const PoseObservation& o : observations) {
    count += projector.SquaredErrorPx(o) <= max_error_px * max_error_px;
  }
  return count;
}

// Eight at a time must count what PoseProjector counts one by one, whatever the thresholds, the
// remainder (counts not a multiple of eight) and the points behind the camera.
TEST(InlierCounterTest, CountsWhatThePoseProjectorCountsOneByOne) {
  Rng rng(7);
  PoseRefineOptions options;
  options.focal_px = 458.0;
  options.baseline_m = 0.11;
  options.disparity_weight = 7.5;
  int total = 0;
  for (int count : {0, 5, 8, 61, 300}) {
    const std::vector<PoseObservation> observations = Scattered(count, rng);
    const InlierCounter counter(observations, options);
    for (int trial = 0; trial < 200; ++trial) {
      const Rigid3d pose(
          RotationFromRollPitchYaw(rng.Uniform(-0.3, 0.3), rng.Uniform(-0.3, 0.3),
                                   rng.Uniform(-0.3, 0.3)),
          Eigen::Vector3d(rng.Uniform(-1, 1), rng.Uniform(-1, 1), rng.Uniform(0, 2)));
      for (double max_error_px : {2.0, 30.0, 300.0}) {
        const int expected = CountOneByOne(observations, pose, options, max_error_px);
        ASSERT_EQ(counter.Count(pose, max_error_px), expected)
            << count << " observations, trial " << trial << ", threshold " << max_error_px;
        total += expected;
      }
    }
  }
  EXPECT_GT(total, 10000);  // The thresholds take some and leave some.
}

// The counter writes the camera point as ((r0 x + r1 y) + r2 z) + t for the first two rows and
// (r6 x + (r7 y + r8 z)) + t for the third: the order of Eigen's fixed-size product in
// PoseProjector::ToCamera as the library is compiled, to the last bit.
TEST(InlierCounterTest, TheProductSumsEachRowLeftToRightLikeEigens) {
  Rng rng(8);
  for (int trial = 0; trial < 100000; ++trial) {
    const Eigen::Matrix3d r =
        RotationFromRollPitchYaw(rng.Uniform(-3, 3), rng.Uniform(-1.5, 1.5), rng.Uniform(-3, 3))
            .toRotationMatrix();
    const Eigen::Vector3d t(rng.Uniform(-9, 9), rng.Uniform(-9, 9), rng.Uniform(-9, 9));
    const Eigen::Vector3d x(rng.Uniform(-50, 50), rng.Uniform(-50, 50), rng.Uniform(-50, 50));
    const Eigen::Vector3d eigen = r * x + t;
    for (int row = 0; row < 3; ++row) {
      const double a = r(row, 0) * x[0], b = r(row, 1) * x[1], c = r(row, 2) * x[2];
      const double ours = (row < 2 ? (a + b) + c : a + (b + c)) + t[row];
      ASSERT_EQ(ours, eigen[row]) << "trial " << trial << " row " << row;
    }
  }
}

}  // namespace
}  // namespace visloc
