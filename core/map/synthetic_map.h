#pragma once
// Synthetic maps of any size with consistent structure (keyframes on a loop, points in front
// of the keyframes that see them, projected pixels, random descriptors, a vocabulary), for
// tests and benchmarks of storage and scaling. They are not built from images.

#include <cstdint>
#include <string>

#include "core/map/map.h"

namespace visloc {

struct SyntheticMapOptions {
  int keyframes = 100;
  int points = 10000;
  int observations_per_point = 4;  // Consecutive keyframes that see each point.
  DescriptorType descriptor_type = DescriptorType::kFloat32;
  int descriptor_dim = 16;
  bool appearance = true;    // Add a vocabulary (branching 8) and keyframe vectors.
  int vocabulary_depth = 2;  // 8^depth words.
  // Keyframe vectors from the descriptors of the points each keyframe sees (as the map builder
  // makes them), so relocalization can work on the map; otherwise random vectors.
  bool appearance_from_descriptors = false;
  uint64_t seed = 1;
  std::string name = "synthetic";  // metadata.name
  // 0: the keyframes walk a loop looking out. Otherwise they walk lanes of this length (m), 3 m
  // apart, back and forth, looking along the walk: a building floor covered row by row.
  double lane_length_m = 0.0;
};

Map MakeSyntheticMap(const SyntheticMapOptions& options);

}  // namespace visloc
