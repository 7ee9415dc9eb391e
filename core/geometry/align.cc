#include "core/geometry/align.h"

#include <Eigen/Geometry>

#include "core/util/check.h"

namespace visloc {

Rigid3d AlignRigid(const std::vector<Eigen::Vector3d>& source,
                   const std::vector<Eigen::Vector3d>& target) {
  VISLOC_CHECK(source.size() == target.size(), "sizes differ: ", source.size(), " vs ",
               target.size());
  VISLOC_CHECK(source.size() >= 3, "need at least 3 point pairs, got ", source.size());
  Eigen::Matrix3Xd src(3, source.size());
  Eigen::Matrix3Xd dst(3, target.size());
  for (size_t i = 0; i < source.size(); ++i) {
    src.col(i) = source[i];
    dst.col(i) = target[i];
  }
  const Eigen::Matrix4d transform = Eigen::umeyama(src, dst, /*with_scaling=*/false);
  return Rigid3d(Eigen::Matrix3d(transform.topLeftCorner<3, 3>()),
                 Eigen::Vector3d(transform.topRightCorner<3, 1>()));
}

}  // namespace visloc
