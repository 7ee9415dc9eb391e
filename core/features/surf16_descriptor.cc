// Harris-SURF16 description: upright 16-D SURF-like descriptors from box sums and a per-image
// table of the smallest Haar wavelet (harris_surf16.h).
#include "core/features/harris_surf16.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <optional>

#include <opencv2/imgproc.hpp>

#include "core/util/cpu_dispatch.h"

namespace visloc {

namespace {

constexpr int kSamplesPerSide = 12;  // 6 per sub-region, 2 sub-regions per side.

// Sample offsets (pixels, relative to the keypoint) and Gaussian weights of the descriptor
// window for one keypoint scale: a 12 s square of 12 x 12 samples, weighted by a Gaussian of
// sigma 3.3 s. Keypoints come in a handful of scales, so these are computed once per scale.
struct DescriptorPattern {
  double scale = 0.0;
  int half_haar = 1;  // Haar wavelet half size (the wavelet is 2 s wide, rounded to even).
  std::array<double, kSamplesPerSide> offsets{};
  std::array<float, kSamplesPerSide * kSamplesPerSide> weights{};
  // The same for DescribeFromWords's steps: for row sy and step i, sixteen lanes holding the
  // weights of samples 2i, 2i + 1, 6 + 2i and 7 + 2i, four lanes each.
  std::array<float, kSamplesPerSide * 3 * 16> lane_weights{};
};

// The samples DescribeFromWords takes at step i of a row: 2i and 2i + 1 of the left sub-region,
// the same of the right one.
constexpr std::array<int, 4> SmallStepSamples(int i) {
  return {2 * i, 2 * i + 1, 6 + 2 * i, 7 + 2 * i};
}

DescriptorPattern MakePattern(double s) {
  DescriptorPattern pattern;
  pattern.scale = s;
  pattern.half_haar = std::max(2, static_cast<int>(std::lround(2 * s)) & ~1) / 2;
  const double gauss = 1.0 / (2.0 * (3.3 * s) * (3.3 * s));
  for (int i = 0; i < kSamplesPerSide; ++i) pattern.offsets[i] = (i - 5.5) * s;
  for (int sy = 0; sy < kSamplesPerSide; ++sy) {
    for (int sx = 0; sx < kSamplesPerSide; ++sx) {
      const double ox = pattern.offsets[sx], oy = pattern.offsets[sy];
      pattern.weights[sy * kSamplesPerSide + sx] =
          static_cast<float>(std::exp(-(ox * ox + oy * oy) * gauss));
    }
    for (int i = 0; i < 3; ++i) {
      const std::array<int, 4> sx = SmallStepSamples(i);
      for (int lane = 0; lane < 16; ++lane) {
        pattern.lane_weights[(sy * 3 + i) * 16 + lane] =
            pattern.weights[sy * kSamplesPerSide + sx[lane / 4]];
      }
    }
  }
  return pattern;
}

// Box sums over an integral image (CV_32S, (h+1) x (w+1)); coordinates are clamped to the
// image so windows that overhang the border read the edge.
class BoxSums {
 public:
  explicit BoxSums(const cv::Mat& grey) {
    cv::integral(grey, integral_, CV_32S);
    stride_ = static_cast<int>(integral_.step1());
    data_ = integral_.ptr<int>(0);
    max_x_ = integral_.cols - 1;
    max_y_ = integral_.rows - 1;
  }
  // Sum over [x0, x1) x [y0, y1).
  int Sum(int x0, int y0, int x1, int y1) const {
    x0 = std::clamp(x0, 0, max_x_);
    x1 = std::clamp(x1, 0, max_x_);
    y0 = std::clamp(y0, 0, max_y_);
    y1 = std::clamp(y1, 0, max_y_);
    return data_[y1 * stride_ + x1] - data_[y0 * stride_ + x1] - data_[y1 * stride_ + x0] +
           data_[y0 * stride_ + x0];
  }
  // Row y of the integral image: entry x is the sum over [0, x) x [0, y).
  const int* Row(int y) const { return data_ + y * stride_; }
  int max_x() const { return max_x_; }  // The image's width: the last integral column.
  // True when [x0, x1) x [y0, y1) lies inside the image, so no coordinate needs clamping.
  bool Contains(int x0, int y0, int x1, int y1) const {
    return x0 >= 0 && y0 >= 0 && x1 <= max_x_ && y1 <= max_y_;
  }
  // Haar responses of half size `half` at (x, y) for a window inside the image: right minus
  // left half, bottom minus top half, from 8 integral reads (the halves share their edges).
  void HaarInside(int x, int y, int half, float* dx, float* dy) const {
    const int* top = data_ + (y - half) * stride_ + x;
    const int* mid = data_ + y * stride_ + x;
    const int* bottom = data_ + (y + half) * stride_ + x;
    *dx = static_cast<float>(bottom[half] - top[half] + bottom[-half] - top[-half] -
                             2 * (bottom[0] - top[0]));
    *dy = static_cast<float>(bottom[half] + top[half] - bottom[-half] - top[-half] -
                             2 * (mid[half] - mid[-half]));
  }
  // The same anywhere: windows that overhang the border read the edge.
  void HaarClamped(int x, int y, int half, float* dx, float* dy) const {
    *dx = static_cast<float>(Sum(x, y - half, x + half, y + half) -
                             Sum(x - half, y - half, x, y + half));
    *dy = static_cast<float>(Sum(x - half, y, x + half, y + half) -
                             Sum(x - half, y - half, x + half, y));
  }

 private:
  cv::Mat integral_;
  const int* data_ = nullptr;
  int stride_ = 0, max_x_ = 0, max_y_ = 0;
};

// Row y of SmallHaar's table from image rows y - 1 (`above`) and y. Restricted: the pairs never
// overlap the image (8-bit pointers may alias anything).
VISLOC_SIMD_CLONES void SmallHaarRow(const uint8_t* __restrict above, const uint8_t* __restrict row,
                                     int cols, int16_t* __restrict pairs) {
  pairs[0] = pairs[1] = 0;
  for (int x = 1; x < cols; ++x) {
    // Pixels a b / c d around the sample point (x, y), which is d's top-left corner.
    const int a = above[x - 1], b = above[x], c = row[x - 1], d = row[x];
    pairs[2 * x] = static_cast<int16_t>((b + d) - (a + c));
    pairs[2 * x + 1] = static_cast<int16_t>((c + d) - (a + b));
  }
}

// Haar responses of the smallest wavelet (half size 1: 2x2 pixels) at every pixel, from the
// image directly. The finest scale's samples (most of a query's) then read two values instead
// of eight integral-image entries. The values are the integers BoxSums::HaarInside gives, so
// descriptors do not depend on which path computed them.
class SmallHaar {
 public:
  // (dx, dy) pairs, adjacent so that one 32-bit load reads a sample.
  explicit SmallHaar(const cv::Mat& grey) : pairs_(grey.size(), CV_16SC2) {
    pairs_.row(0).setTo(0);
    for (int y = 1; y < grey.rows; ++y) {
      SmallHaarRow(grey.ptr<uint8_t>(y - 1), grey.ptr<uint8_t>(y), grey.cols,
                   pairs_.ptr<int16_t>(y));
    }
  }
  // True when samples at x in [x0, x1] and y in [y0, y1] have their whole wavelet inside.
  bool Contains(int x0, int y0, int x1, int y1) const {
    return x0 >= 1 && y0 >= 1 && x1 < pairs_.cols && y1 < pairs_.rows;
  }
  // Row y's pairs, each (dx | dy << 16) in a little-endian 32-bit word.
  const int32_t* PairRow(int y) const { return pairs_.ptr<int32_t>(y); }

 private:
  cv::Mat pairs_;
};

inline int RoundToInt(double v) { return static_cast<int>(std::floor(v + 0.5)); }

// The descriptor from its 16 sums: unit length (contrast invariance), or as is when all vanish.
void Normalize(const std::array<float, 16>& sums, float* descriptor) {
  double norm = 0;
  for (int j = 0; j < 16; ++j) norm += sums[j] * sums[j];
  norm = std::sqrt(norm);
  for (int j = 0; j < 16; ++j) {
    descriptor[j] = norm > 1e-12 ? static_cast<float>(sums[j] / norm) : sums[j];
  }
}

// The descriptor of one keypoint from its sample grid (xs, ys) and the wavelet responses
// `haar(x, y, &dx, &dy)`: per sub-region (sum dx, sum dy, sum |dx|, sum |dy|), Gaussian
// weighted, normalized to unit length. One accumulation order for every response source. Each
// sub-region sums into two accumulators (even and odd samples) so that consecutive samples do
// not wait on each other's additions.
template <typename HaarAt>
void DescribeOne(const DescriptorPattern& pattern, const std::array<int, kSamplesPerSide>& xs,
                 const std::array<int, kSamplesPerSide>& ys, HaarAt&& haar, float* descriptor) {
  std::array<float, 16> sums{};
  // One sample's weighted (dx, dy, |dx|, |dy|) added to `acc`.
  const auto add_sample = [&](int x, int y, float w, float* acc) {
    float dx, dy;
    haar(x, y, &dx, &dy);
    acc[0] += w * dx;
    acc[1] += w * dy;
    acc[2] += w * std::abs(dx);
    acc[3] += w * std::abs(dy);
  };
  for (int sy = 0; sy < kSamplesPerSide; ++sy) {
    const int y = ys[sy];
    const float* weights = &pattern.weights[sy * kSamplesPerSide];
    for (int column = 0; column < 2; ++column) {
      float even[4] = {0, 0, 0, 0}, odd[4] = {0, 0, 0, 0};
      for (int sx = 6 * column; sx < 6 * column + 6; sx += 2) {
        add_sample(xs[sx], y, weights[sx], even);
        add_sample(xs[sx + 1], y, weights[sx + 1], odd);
      }
      float* cell = &sums[4 * ((sy / 6) * 2 + column)];
      for (int c = 0; c < 4; ++c) cell[c] += even[c] + odd[c];
    }
  }
  Normalize(sums, descriptor);
}

// (dx, dy, |dx|, |dy|) of the samples at columns x[0..3] of a response-table row, in lanes
// 4j ... 4j + 3 for sample j. (Written to `out`: a vector return value would have an ABI that
// differs between the clones.)
inline void FourSamples(const int32_t* row, const int* x, Floats16* out) {
  const int32_t words[4] = {row[x[0]], row[x[1]], row[x[2]], row[x[3]]};
  Shorts8 pairs;  // dx0 dy0 dx1 dy1 ... (little-endian words)
  std::memcpy(&pairs, words, sizeof pairs);
  const Floats8 values = __builtin_convertvector(pairs, Floats8);
  const Floats16 spread =
      __builtin_shufflevector(values, values, 0, 1, 0, 1, 2, 3, 2, 3, 4, 5, 4, 5, 6, 7, 6, 7);
  const Ints16 keep_sign = {-1, -1, 0x7fffffff, 0x7fffffff, -1, -1, 0x7fffffff, 0x7fffffff,
                            -1, -1, 0x7fffffff, 0x7fffffff, -1, -1, 0x7fffffff, 0x7fffffff};
  *out = reinterpret_cast<Floats16>(reinterpret_cast<Ints16>(spread) & keep_sign);
}

// DescribeOne from wavelet responses given as words (dx | dy << 16, SmallHaar's layout): sample
// (sx, sy) of the pattern is rows[sy][xs[sx]]. Four samples at a time in sixteen lanes: per row
// of the pattern, step i (0 to 2) takes the samples 2i and 2i + 1 of the left sub-region and of
// the right one, each sample's four values (dx, dy, |dx|, |dy|) in its own four lanes, so the
// lanes are DescribeOne's four accumulators (left even, left odd, right even, right odd). Each
// value goes through DescribeOne's operations in its order, so the descriptor has the same bits.
VISLOC_SIMD_CLONES void DescribeFromWords(const DescriptorPattern& pattern,
                                          const std::array<int, kSamplesPerSide>& xs,
                                          const int32_t* const* rows, float* descriptor) {
  std::array<float, 16> sums{};
  for (int sy = 0; sy < kSamplesPerSide; ++sy) {
    const int32_t* row = rows[sy];
    Floats16 acc = {};
    for (int i = 0; i < 3; ++i) {
      const std::array<int, 4> sx = SmallStepSamples(i);
      const int x[4] = {xs[sx[0]], xs[sx[1]], xs[sx[2]], xs[sx[3]]};
      Floats16 w, samples;
      std::memcpy(&w, &pattern.lane_weights[(sy * 3 + i) * 16], sizeof w);
      FourSamples(row, x, &samples);
      acc += w * samples;
    }
    // cell += even + odd, for the left sub-region's cell and the right one's (adjacent in sums).
    const Floats8 even = __builtin_shufflevector(acc, acc, 0, 1, 2, 3, 8, 9, 10, 11);
    const Floats8 odd = __builtin_shufflevector(acc, acc, 4, 5, 6, 7, 12, 13, 14, 15);
    float* cells = &sums[8 * (sy / 6)];
    Floats8 both;
    std::memcpy(&both, cells, sizeof both);
    both += even + odd;
    std::memcpy(cells, &both, sizeof both);
  }
  Normalize(sums, descriptor);
}

// Larger wavelets (half size 2 and up) are computed from the integral image a row of the pattern
// at a time: the samples of a row lie s apart and their wavelets 2 half wide overlap, so the
// responses at every column of the row's span (11 s + 1 columns) cost fewer reads than eight
// per sample, and the loop over consecutive columns vectorizes. Within these bounds a response
// fits the words' 16 bits (at most 2 half^2 255) and the span the scratch rows.
constexpr int kMaxSpanHalf = 8;
constexpr int kMaxSpan = 64;

// The words of BoxSums::HaarInside's responses of half size `half` at columns x0 ... x0 + span -
// 1 of each pattern row ys[sy], into row sy of `words` (kMaxSpan apart): the same integers.
VISLOC_SIMD_CLONES void HaarWordsOfRows(const BoxSums& boxes,
                                        const std::array<int, kSamplesPerSide>& ys, int half,
                                        int x0, int span, int32_t* __restrict words) {
  for (int sy = 0; sy < kSamplesPerSide; ++sy) {
    const int* __restrict top = boxes.Row(ys[sy] - half) + x0;
    const int* __restrict mid = boxes.Row(ys[sy]) + x0;
    const int* __restrict bottom = boxes.Row(ys[sy] + half) + x0;
    int32_t* __restrict out = words + sy * kMaxSpan;
    for (int i = 0; i < span; ++i) {
      const int dx = bottom[i + half] - top[i + half] + bottom[i - half] - top[i - half] -
                     2 * (bottom[i] - top[i]);
      const int dy = bottom[i + half] + top[i + half] - bottom[i - half] - top[i - half] -
                     2 * (mid[i + half] - mid[i - half]);
      out[i] = static_cast<int32_t>((static_cast<uint32_t>(dx) & 0xffffu) |
                                    (static_cast<uint32_t>(dy) << 16));
    }
  }
}

// DescribeOne with BoxSums::HaarInside's responses (the window inside the image), through
// HaarWordsOfRows and DescribeFromWords; false, describing nothing, beyond their bounds.
bool DescribeOneFromRows(const DescriptorPattern& pattern,
                         const std::array<int, kSamplesPerSide>& xs,
                         const std::array<int, kSamplesPerSide>& ys, const BoxSums& boxes,
                         float* descriptor) {
  const int half = pattern.half_haar, span = xs.back() - xs.front() + 1;
  if (half > kMaxSpanHalf || span > kMaxSpan) return false;
  // Whole vectors of columns (the loop then has no scalar remainder), moved left where they
  // would pass the image's right edge.
  const int padded = (span + 15) / 16 * 16;
  const int x0 = std::max(half, std::min(xs.front(), boxes.max_x() - half - padded + 1));
  const int columns_computed = std::min(padded, boxes.max_x() - half - x0 + 1);
  std::array<int32_t, kSamplesPerSide * kMaxSpan> words;
  HaarWordsOfRows(boxes, ys, half, x0, columns_computed, words.data());
  std::array<const int32_t*, kSamplesPerSide> rows;
  for (int sy = 0; sy < kSamplesPerSide; ++sy) rows[sy] = &words[sy * kMaxSpan];
  std::array<int, kSamplesPerSide> columns;
  for (int sx = 0; sx < kSamplesPerSide; ++sx) columns[sx] = xs[sx] - x0;
  DescribeFromWords(pattern, columns, rows.data(), descriptor);
  return true;
}

}  // namespace

cv::Mat HarrisSurf16Extractor::Describe(const cv::Mat& grey,
                                        const std::vector<Keypoint>& keypoints) const {
  // Both response sources are built on first use: a query needs only the small wavelets.
  std::optional<BoxSums> boxes;
  std::optional<SmallHaar> small;
  cv::Mat descriptors(static_cast<int>(keypoints.size()), 16, CV_32F);
  std::vector<DescriptorPattern> patterns;
  for (size_t i = 0; i < keypoints.size(); ++i) {
    const Keypoint& k = keypoints[i];
    auto pattern = std::find_if(patterns.begin(), patterns.end(),
                                [&](const DescriptorPattern& p) { return p.scale == k.scale_px; });
    if (pattern == patterns.end()) {
      patterns.push_back(MakePattern(k.scale_px));
      pattern = patterns.end() - 1;
    }
    const int half = pattern->half_haar;
    std::array<int, kSamplesPerSide> xs, ys;
    for (int j = 0; j < kSamplesPerSide; ++j) {
      xs[j] = RoundToInt(k.pixel.x() + pattern->offsets[j]);
      ys[j] = RoundToInt(k.pixel.y() + pattern->offsets[j]);
    }
    float* d = descriptors.ptr<float>(static_cast<int>(i));
    if (half == 1) {
      if (!small) small.emplace(grey);
      if (small->Contains(xs.front(), ys.front(), xs.back(), ys.back())) {
        std::array<const int32_t*, kSamplesPerSide> rows;
        for (int sy = 0; sy < kSamplesPerSide; ++sy) rows[sy] = small->PairRow(ys[sy]);
        DescribeFromWords(*pattern, xs, rows.data(), d);
        continue;
      }
    }
    if (!boxes) boxes.emplace(grey);
    if (boxes->Contains(xs.front() - half, ys.front() - half, xs.back() + half, ys.back() + half)) {
      if (DescribeOneFromRows(*pattern, xs, ys, *boxes, d)) continue;
      DescribeOne(
          *pattern, xs, ys,
          [&](int x, int y, float* dx, float* dy) { boxes->HaarInside(x, y, half, dx, dy); }, d);
    } else {
      DescribeOne(
          *pattern, xs, ys,
          [&](int x, int y, float* dx, float* dy) { boxes->HaarClamped(x, y, half, dx, dy); }, d);
    }
  }
  return descriptors;
}

}  // namespace visloc
