#include "dataset/ply.h"

#include <cstring>
#include <fstream>
#include <sstream>

#include "core/util/check.h"
#include "core/util/text_file.h"

namespace visloc {
namespace {
constexpr size_t kVertexBytes = 3 * sizeof(float) + 3;
}  // namespace

void WritePly(const std::string& path, const std::vector<ColoredPoint>& points,
              const std::string& comment) {
  std::string out = StrCat("ply\nformat binary_little_endian 1.0\ncomment ", comment,
                           "\nelement vertex ", points.size(),
                           "\nproperty float x\nproperty float y\nproperty float z\n"
                           "property uchar red\nproperty uchar green\nproperty uchar blue\n"
                           "end_header\n");
  out.reserve(out.size() + points.size() * kVertexBytes);
  for (const ColoredPoint& p : points) {
    const float xyz[3] = {static_cast<float>(p.position.x()), static_cast<float>(p.position.y()),
                          static_cast<float>(p.position.z())};
    out.append(reinterpret_cast<const char*>(xyz), sizeof(xyz));
    out.append(reinterpret_cast<const char*>(p.rgb.data()), 3);
  }
  WriteFileAtomically(path, out);
}

std::vector<ColoredPoint> ReadPly(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path + ": cannot open file");
  std::string line;
  size_t count = 0;
  bool binary = false;
  while (std::getline(in, line) && line != "end_header") {
    if (line == "format binary_little_endian 1.0") binary = true;
    if (line.rfind("element vertex ", 0) == 0) count = std::stoul(line.substr(15));
  }
  if (!binary || line != "end_header") throw InputError(path + ": not a binary little-endian PLY");
  std::vector<ColoredPoint> points(count);
  for (ColoredPoint& p : points) {
    char record[kVertexBytes];
    if (!in.read(record, kVertexBytes)) throw InputError(path + ": truncated PLY");
    float xyz[3];
    std::memcpy(xyz, record, sizeof(xyz));
    p.position = Eigen::Vector3d(xyz[0], xyz[1], xyz[2]);
    std::memcpy(p.rgb.data(), record + sizeof(xyz), 3);
  }
  return points;
}

}  // namespace visloc
