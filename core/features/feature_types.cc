#include "core/features/feature_types.h"

#include "core/util/check.h"

namespace visloc {

std::string ToString(DescriptorType type) {
  return type == DescriptorType::kFloat32 ? "float32" : "binary";
}

DescriptorType ParseDescriptorType(const std::string& text) {
  if (text == "float32") return DescriptorType::kFloat32;
  if (text == "binary") return DescriptorType::kBinary;
  throw InputError(StrCat("unknown descriptor type '", text, "' (expected float32 or binary)"));
}

FeatureSet FeatureSet::Subset(const std::vector<int>& indices) const {
  FeatureSet subset;
  subset.keypoints.reserve(indices.size());
  subset.descriptors = cv::Mat(static_cast<int>(indices.size()), descriptors.cols, descriptors.type());
  for (size_t j = 0; j < indices.size(); ++j) {
    subset.keypoints.push_back(keypoints[indices[j]]);
    descriptors.row(indices[j]).copyTo(subset.descriptors.row(static_cast<int>(j)));
  }
  return subset;
}

void DescriptorMatchOptions::Check() const {
  VISLOC_CHECK(max_float_distance > 0 && max_binary_distance > 0, "descriptor distance limits ",
               max_float_distance, ", ", max_binary_distance);
  VISLOC_CHECK(ratio > 0 && ratio <= 1, "descriptor ratio ", ratio);
}

}  // namespace visloc
