#pragma once
// 3D points bucketed in cubes, for "what lies within r of here" over a map's worth of points
// (map merge fuses duplicates with it, map update looks for what a session saw). A query
// radius must not exceed the cube side.

#include <cmath>
#include <cstdint>
#include <unordered_map>
#include <vector>

#include <Eigen/Core>

namespace visloc::mapping {

class PointGrid {
 public:
  explicit PointGrid(double cell_m) : cell_m_(cell_m) {}

  // `id` is the caller's (a point index, an observation index, ...).
  void Add(const Eigen::Vector3d& position, int id) { cells_[Key(Cell(position))].push_back({position, id}); }

  // Calls visit(id, position) for every point within `radius_m` (<= the cell side) of `p`.
  template <typename Visit>
  void ForEachWithin(const Eigen::Vector3d& p, double radius_m, Visit&& visit) const {
    const Eigen::Vector3i c = Cell(p);
    for (int dx = -1; dx <= 1; ++dx) {
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dz = -1; dz <= 1; ++dz) {
          auto it = cells_.find(Key(c + Eigen::Vector3i(dx, dy, dz)));
          if (it == cells_.end()) continue;
          for (const Entry& e : it->second) {
            if ((e.position - p).norm() <= radius_m) visit(e.id, e.position);
          }
        }
      }
    }
  }

 private:
  struct Entry {
    Eigen::Vector3d position;
    int id;
  };
  Eigen::Vector3i Cell(const Eigen::Vector3d& p) const { return (p / cell_m_).array().floor().cast<int>(); }
  static int64_t Key(const Eigen::Vector3i& c) {
    return (static_cast<int64_t>(c.x()) * 73856093) ^ (static_cast<int64_t>(c.y()) * 19349663) ^
           (static_cast<int64_t>(c.z()) * 83492791);
  }
  double cell_m_;
  std::unordered_map<int64_t, std::vector<Entry>> cells_;
};

}  // namespace visloc::mapping
