#include "core/geometry/align.h"

#include <gtest/gtest.h>

#include "core/util/check.h"

namespace visloc {
namespace {

TEST(AlignRigidTest, RecoversKnownTransformExactly) {
  const Rigid3d target_from_source(RotationFromRollPitchYaw(0.2, -0.1, 1.3),
                                   Eigen::Vector3d(0.5, -1.0, 2.0));
  std::vector<Eigen::Vector3d> source, target;
  for (int i = 0; i < 20; ++i) {
    const Eigen::Vector3d p(std::sin(i * 0.7) * 3, std::cos(i * 1.3) * 2, 0.1 * i);
    source.push_back(p);
    target.push_back(target_from_source * p);
  }
  EXPECT_TRUE(ApproxEqual(AlignRigid(source, target), target_from_source, 1e-9, 1e-7));
}

TEST(AlignRigidTest, RejectsTooFewPoints) {
  EXPECT_THROW(AlignRigid({Eigen::Vector3d::Zero()}, {Eigen::Vector3d::Zero()}), CheckError);
}

}  // namespace
}  // namespace visloc
