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

void DescriptorMatchOptions::Check() const {
  VISLOC_CHECK(max_float_distance > 0 && max_binary_distance > 0, "descriptor distance limits ",
               max_float_distance, ", ", max_binary_distance);
  VISLOC_CHECK(ratio > 0 && ratio <= 1, "descriptor ratio ", ratio);
}

}  // namespace visloc
