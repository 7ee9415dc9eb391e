#pragma once
// The vocabulary of image features that every layer above shares: keypoints, descriptor sets,
// the settings a map records about its detector and descriptor, and how descriptors are compared
// and accepted as matches. Below the map model, so that the extractors (core/features) and the
// map (core/map) both build on it without depending on each other.

#include <limits>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

namespace visloc {

// How descriptors are compared: float vectors by L2 distance, bit strings by Hamming distance.
enum class DescriptorType { kFloat32, kBinary };
std::string ToString(DescriptorType type);
// "float32" or "binary"; throws InputError otherwise.
DescriptorType ParseDescriptorType(const std::string& text);

// The detector/descriptor a map was built with. Localization must use the same settings.
struct FeatureSettings {
  std::string kind;  // e.g. "harris_surf16" (the paper's) or "orb"
  DescriptorType descriptor_type = DescriptorType::kFloat32;
  int descriptor_dim = 0;  // Floats (kFloat32) or bytes (kBinary) per descriptor.
  std::vector<std::pair<std::string, double>> params;  // Detector/descriptor parameters.
  // The OpenCV type of one descriptor row: CV_32F or CV_8U.
  int cv_type() const { return descriptor_type == DescriptorType::kFloat32 ? CV_32F : CV_8U; }
};

struct Keypoint {
  Eigen::Vector2f pixel = Eigen::Vector2f::Zero();  // Sub-pixel position, image pixels.
  float scale_px = 1.0f;  // Detection scale (Gaussian sigma for Harris, size/2 for ORB).
  float response = 0.0f;  // Detector response: larger is stronger.
};

struct FeatureSet {
  std::vector<Keypoint> keypoints;
  cv::Mat descriptors;  // One row per keypoint: CV_32F (float32) or CV_8U (binary).
  size_t size() const { return keypoints.size(); }
  // The keypoints `indices` (ascending) with their descriptors.
  FeatureSet Subset(const std::vector<int>& indices) const;
};

// When two descriptors are taken to show the same scene point: close enough, and clearly closer
// than the runner-up (Lowe's ratio test). One set of thresholds for every descriptor matcher
// (guided tracking in mapping and localization, relocalization, loop closure).
struct DescriptorMatchOptions {
  float max_float_distance = 0.6f;    // L2 between unit-norm float descriptors.
  float max_binary_distance = 80.0f;  // Hamming bits, of 256.
  float ratio = 0.85f;                // Best must be below ratio * second best.
  float MaxDistance(DescriptorType type) const {
    return type == DescriptorType::kBinary ? max_binary_distance : max_float_distance;
  }
  void Check() const;
};

// Keeps the nearest and second-nearest candidates of a descriptor search, for Lowe's ratio test
// (a match is distinctive when best < ratio * second).
struct NearestTwo {
  float best = std::numeric_limits<float>::max();
  float second = std::numeric_limits<float>::max();
  int best_index = -1;
  void Offer(float distance, int index) {
    if (distance < best) {
      second = best;
      best = distance;
      best_index = index;
    } else if (distance < second) {
      second = distance;
    }
  }
  // True when there is a best candidate within `max_distance` that passes the ratio test.
  bool Distinctive(float ratio, float max_distance) const {
    return best_index >= 0 && best <= max_distance && best <= ratio * second;
  }
};

}  // namespace visloc
