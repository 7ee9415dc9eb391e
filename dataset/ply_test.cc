#include "dataset/ply.h"

#include <gtest/gtest.h>

#include <filesystem>

#include "core/util/temp_dir.h"

namespace visloc {
namespace {

TEST(PlyTest, WrittenCloudReadsBackWithItsHeader) {
  TempDir dir;
  const std::vector<ColoredPoint> points = {{Eigen::Vector3d(1.5, -2, 0.25), {255, 0, 0}},
                                            {Eigen::Vector3d(0, 0, 3), {200, 200, 200}}};
  WritePly(dir.File("c.ply"), points, "test cloud");
  const auto back = ReadPly(dir.File("c.ply"));
  ASSERT_EQ(back.size(), 2u);
  EXPECT_EQ(back[0].position, points[0].position);
  EXPECT_EQ(back[1].rgb, points[1].rgb);
  const std::string header =
      "ply\nformat binary_little_endian 1.0\ncomment test cloud\nelement vertex 2\n"
      "property float x\nproperty float y\nproperty float z\nproperty uchar red\n"
      "property uchar green\nproperty uchar blue\nend_header\n";
  EXPECT_EQ(std::filesystem::file_size(dir.File("c.ply")), header.size() + 2 * 15);
}

}  // namespace
}  // namespace visloc
