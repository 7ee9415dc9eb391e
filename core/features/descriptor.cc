#include "core/features/descriptor.h"

#include <opencv2/core/hal/hal.hpp>

#include "core/util/check.h"
#include "core/util/cpu_dispatch.h"

namespace visloc {

float HammingDistance(const uchar* a, const uchar* b, int bytes) {
  return static_cast<float>(cv::hal::normHamming(a, b, bytes));
}

Float16Columns::Float16Columns(const cv::Mat& descriptors, const std::vector<uint32_t>& rows)
    : count_(static_cast<int>(rows.size())), columns_(16 * rows.size()) {
  VISLOC_CHECK(descriptors.type() == CV_32F && descriptors.cols == 16, "16-float descriptors");
  for (int j = 0; j < count_; ++j) {
    VISLOC_CHECK(rows[j] < static_cast<uint32_t>(descriptors.rows), "descriptor row ", rows[j],
                 " of ", descriptors.rows);
    const float* row = descriptors.ptr<float>(static_cast<int>(rows[j]));
    for (int d = 0; d < 16; ++d) columns_[d * count_ + j] = row[d];
  }
}

namespace {

// Float16Columns::Distances, out of the class so it can be cloned for AVX2. The lanes and their
// order are DescriptorDistance's: lane l sums dimensions l, l + 4, l + 8, l + 12 from 0, and the
// result is sqrt((l0 + l1) + (l2 + l3)).
VISLOC_AVX2_CLONE void ColumnDistances(const float* __restrict query,
                                       const float* __restrict columns, int count,
                                       float* __restrict out) {
  for (int j = 0; j < count; ++j) {
    float lanes[4] = {0, 0, 0, 0};
    for (int i = 0; i < 16; i += 4) {
      for (int l = 0; l < 4; ++l) {
        const float diff = query[i + l] - columns[(i + l) * count + j];
        lanes[l] += diff * diff;
      }
    }
    out[j] = std::sqrt((lanes[0] + lanes[1]) + (lanes[2] + lanes[3]));
  }
}

}  // namespace

void Float16Columns::Distances(const float* query, float* out) const {
  ColumnDistances(query, columns_.data(), count_, out);
}

}  // namespace visloc
