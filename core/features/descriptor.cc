#include "core/features/descriptor.h"

#include <algorithm>
#include <limits>

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

// Sixteen lanes (Floats16, Ints16 of cpu_dispatch.h). (Eight lanes left the AVX-512 clone
// half-width: relocalization 5-8% slower on real frames.)
constexpr int kLanes = 16;

// The squared distance of `query` to descriptors j0 ... j0 + 15 of the columns. The lanes and
// their order are DescriptorDistance's: lane l sums dimensions l, l + 4, l + 8, l + 12 from 0,
// and the sum is (l0 + l1) + (l2 + l3), before its square root. (Written to `out`: a vector
// return value would have an ABI that differs between the clones.)
inline void SquaredDistancesOfLanes(const float* query, const float* columns, int count, int j0,
                                    Floats16* out) {
  Floats16 sums[4] = {};
  for (int i = 0; i < 16; i += 4) {
    for (int k = 0; k < 4; ++k) {
      Floats16 column;
      __builtin_memcpy(&column, columns + (i + k) * count + j0, sizeof column);
      const Floats16 diff = query[i + k] - column;
      sums[k] += diff * diff;
    }
  }
  *out = (sums[0] + sums[1]) + (sums[2] + sums[3]);
}

// The same for one descriptor j.
inline float SquaredDistance(const float* query, const float* columns, int count, int j) {
  float lanes[4] = {0, 0, 0, 0};
  for (int i = 0; i < 16; i += 4) {
    for (int l = 0; l < 4; ++l) {
      const float diff = query[i + l] - columns[(i + l) * count + j];
      lanes[l] += diff * diff;
    }
  }
  return (lanes[0] + lanes[1]) + (lanes[2] + lanes[3]);
}

// Float16Columns::Nearest, on squared distances: the square root is monotonic and correctly
// rounded, so the nearest two's roots are the roots' nearest two, and the first index of the
// smallest square is that of the smallest root unless two squares round to one root, a tie
// that no ratio test passes. Lane l keeps NearestTwo's state over descriptors l, l + 16, ...; the
// lanes are merged as one pass in index order would have left them: the smallest best, at its
// first index, and as second the smallest of the other lanes' bests and the winner's second. The
// remainder (count % 16, the last indices) is offered in order after that.
VISLOC_SIMD_CLONES NearestTwo ColumnNearest(const float* query, const float* columns, int count) {
  constexpr float kFar = std::numeric_limits<float>::max();
  Floats16 best, second;
  Ints16 best_index, index;
  for (int l = 0; l < kLanes; ++l) {
    best[l] = second[l] = kFar;
    best_index[l] = -1;
    index[l] = l;
  }
  int j0 = 0;
  for (; j0 + kLanes <= count; j0 += kLanes, index += kLanes) {
    Floats16 squared;
    SquaredDistancesOfLanes(query, columns, count, j0, &squared);
    const Ints16 closer = squared < best;
    second = closer ? best : (squared < second ? squared : second);
    best_index = closer ? index : best_index;
    best = closer ? squared : best;
  }
  NearestTwo nearest;  // In squared distances until the end.
  int winner = -1;
  for (int l = 0; l < kLanes; ++l) {
    if (best_index[l] < 0) continue;
    if (winner < 0 || best[l] < best[winner] ||
        (best[l] == best[winner] && best_index[l] < best_index[winner])) {
      winner = l;
    }
  }
  if (winner >= 0) {
    nearest.best = best[winner];
    nearest.best_index = best_index[winner];
    // Another lane's own second is never below its best.
    for (int l = 0; l < kLanes; ++l) {
      nearest.second = std::min(nearest.second, l == winner ? second[l] : best[l]);
    }
  }
  for (int j = j0; j < count; ++j) nearest.Offer(SquaredDistance(query, columns, count, j), j);
  // Roots, except of "none yet".
  if (nearest.best < kFar) nearest.best = std::sqrt(nearest.best);
  if (nearest.second < kFar) nearest.second = std::sqrt(nearest.second);
  return nearest;
}

// Float16Columns::NearestOf: the distances a block at a time, a loop over consecutive
// descriptors that the compiler vectorizes, then the first smallest in order. A range of at most
// sixteen (a vocabulary node's children) is one vector of lanes when the sixteen columns from
// `first` lie within the array.
VISLOC_SIMD_CLONES int ColumnArgMin(const float* query, const float* columns, int count, int first,
                                    int n) {
  int best = -1;
  float best_distance = std::numeric_limits<float>::max();
  if (n <= kLanes && first + kLanes <= count) {
    Floats16 squared;
    SquaredDistancesOfLanes(query, columns, count, first, &squared);
    for (int l = 0; l < n; ++l) {
      const float distance = std::sqrt(squared[l]);
      if (distance < best_distance) {
        best_distance = distance;
        best = first + l;
      }
    }
    return best;
  }
  constexpr int kBlock = 64;
  float distance[kBlock];
  for (int j0 = first; j0 < first + n; j0 += kBlock) {
    const int m = std::min(kBlock, first + n - j0);
    for (int j = 0; j < m; ++j) {
      distance[j] = std::sqrt(SquaredDistance(query, columns, count, j0 + j));
    }
    for (int j = 0; j < m; ++j) {
      if (distance[j] < best_distance) {
        best_distance = distance[j];
        best = j0 + j;
      }
    }
  }
  return best;
}

// Float16Columns::SquaredDistances: whole vectors, stored whole, while sixteen columns from j
// lie within the array (out has room: the lanes past the range are computed and left there),
// then one at a time.
VISLOC_SIMD_CLONES void ColumnSquaredDistances(const float* query, const float* columns, int count,
                                               int first, int n, float* out) {
  int j = first;
  for (; j < first + n && j + kLanes <= count; j += kLanes) {
    Floats16 squared;
    SquaredDistancesOfLanes(query, columns, count, j, &squared);
    __builtin_memcpy(out + (j - first), &squared, sizeof squared);
  }
  for (; j < first + n; ++j) out[j - first] = SquaredDistance(query, columns, count, j);
}

}  // namespace

void Float16Columns::SquaredDistances(const float* query, int first, int n, float* out) const {
  VISLOC_CHECK(first >= 0 && n >= 0 && first + n <= count_, "descriptor range ", first, " + ", n,
               " of ", count_);
  ColumnSquaredDistances(query, columns_.data(), count_, first, n, out);
}

int Float16Columns::NearestOf(const float* query, int first, int count) const {
  VISLOC_CHECK(first >= 0 && count >= 0 && first + count <= count_, "descriptor range ", first,
               " + ", count, " of ", count_);
  return ColumnArgMin(query, columns_.data(), count_, first, count);
}

NearestTwo Float16Columns::Nearest(const float* query) const {
  return ColumnNearest(query, columns_.data(), count_);
}

}  // namespace visloc
