// Test tool: a big map made of COPIES copies of a real (built) map, laid out on a grid SPACING
// metres apart in the map's x-z plane, for serving maps larger than a memory bound. Copy 0 stays
// where it was, so the query sequences' ground truth holds for it, and it comes first: ties in
// appearance (every copy looks the same) go to the lowest keyframe. Points stay in trajectory
// order copy by copy, as the mapper writes them.
// Usage: tile_map IN.db OUT.db COPIES SPACING_M
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>

#include "core/map/map.h"
#include "mapstore/map_store.h"

namespace {

visloc::Map Tile(const visloc::Map& one, int copies, double spacing_m) {
  visloc::Map tiled = one;
  tiled.metadata.name = one.metadata.name + "-tiled";
  tiled.metadata.lineage =
      "tile(" + std::to_string(copies) + " copies of '" + one.metadata.name + "')";
  tiled.keyframes.clear();
  tiled.points.clear();
  tiled.observations.clear();
  tiled.appearance.keyframe_vectors.clear();
  tiled.descriptors = cv::Mat(0, one.descriptors.cols, one.descriptors.type());
  const int columns = static_cast<int>(std::ceil(std::sqrt(copies)));
  for (int c = 0; c < copies; ++c) {
    const Eigen::Vector3d offset((c % columns) * spacing_m, 0.0, (c / columns) * spacing_m);
    const auto first_keyframe = static_cast<uint32_t>(tiled.keyframes.size());
    const auto first_point = static_cast<uint32_t>(tiled.points.size());
    for (visloc::Keyframe k : one.keyframes) {
      k.map_from_cam.translation += offset;
      tiled.keyframes.push_back(k);
    }
    for (visloc::MapPoint p : one.points) {
      p.position_in_map += offset;
      tiled.points.push_back(p);
    }
    tiled.descriptors.push_back(one.descriptors);
    for (visloc::Observation o : one.observations) {
      o.keyframe += first_keyframe;
      o.point += first_point;
      tiled.observations.push_back(o);
    }
    for (const visloc::BowVector& v : one.appearance.keyframe_vectors)
      tiled.appearance.keyframe_vectors.push_back(v);
  }
  return tiled;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 5) {
    std::fprintf(stderr, "usage: tile_map IN.db OUT.db COPIES SPACING_M\n");
    return 2;
  }
  try {
    const int copies = std::atoi(argv[3]);
    const double spacing_m = std::atof(argv[4]);
    if (copies < 1 || !(spacing_m > 0)) throw std::runtime_error("COPIES >= 1 and SPACING_M > 0");
    const visloc::Map tiled = Tile(visloc::mapstore::LoadMap(argv[1]), copies, spacing_m);
    visloc::mapstore::SaveMap(tiled, argv[2]);
    std::printf("%s: %zu keyframes, %zu points\n", argv[2], tiled.keyframes.size(),
                tiled.points.size());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "tile_map: %s\n", e.what());
    return 1;
  }
  return 0;
}
