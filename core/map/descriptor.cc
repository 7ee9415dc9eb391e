#include "core/map/descriptor.h"

#include <opencv2/core/hal/hal.hpp>

namespace visloc {

float HammingDistance(const uchar* a, const uchar* b, int bytes) {
  return static_cast<float>(cv::hal::normHamming(a, b, bytes));
}

}  // namespace visloc
