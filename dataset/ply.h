#pragma once
// Binary little-endian PLY point clouds with per-vertex colour, as MeshLab and CloudCompare
// read them: element "vertex" with float x, y, z and uchar red, green, blue.

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace visloc {

struct ColoredPoint {
  Eigen::Vector3d position;
  std::array<uint8_t, 3> rgb;
};

// Writes atomically; `comment` goes into the header. Throws InputError when it cannot write.
void WritePly(const std::string& path, const std::vector<ColoredPoint>& points,
              const std::string& comment);

// Reads back what WritePly writes (for tests and tools). Throws InputError for other files.
std::vector<ColoredPoint> ReadPly(const std::string& path);

}  // namespace visloc
