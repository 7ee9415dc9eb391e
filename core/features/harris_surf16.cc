#include "core/features/harris_surf16.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <optional>

#include <opencv2/imgproc.hpp>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "core/util/check.h"
#include "core/util/cpu_dispatch.h"
#include "core/util/memory.h"
#include "core/util/radix_sort.h"
#include "core/util/timer.h"

namespace visloc {

void HarrisSurf16Options::Check() const {
  VISLOC_CHECK(!scales_px.empty(), "no scales");
  for (double s : scales_px) VISLOC_CHECK(s > 0.3 && s < 20, "scale ", s);
  VISLOC_CHECK(max_features > 0 && grid_cols > 0 && grid_rows > 0, "feature quotas");
  VISLOC_CHECK(relative_threshold >= 0 && relative_threshold < 1 && cell_relative_threshold >= 0 &&
                   cell_relative_threshold < 1,
               "thresholds ", relative_threshold, ", ", cell_relative_threshold);
}

HarrisSurf16Extractor::HarrisSurf16Extractor(const HarrisSurf16Options& options)
    : options_(options) {
  options_.Check();
  settings_.kind = "harris_surf16";
  settings_.descriptor_type = DescriptorType::kFloat32;
  settings_.descriptor_dim = 16;
  for (size_t i = 0; i < options_.scales_px.size(); ++i) {
    settings_.params.emplace_back("scale_" + std::to_string(i), options_.scales_px[i]);
  }
  settings_.params.emplace_back("harris_k", options_.harris_k);
  settings_.params.emplace_back("relative_threshold", options_.relative_threshold);
  settings_.params.emplace_back("cell_relative_threshold", options_.cell_relative_threshold);
  settings_.params.emplace_back("max_features", options_.max_features);
  settings_.params.emplace_back("grid_cols", options_.grid_cols);
  settings_.params.emplace_back("grid_rows", options_.grid_rows);
  settings_.params.emplace_back("border_px", options_.border_px);
}

namespace {

// Half width of a Gaussian kernel covering about +-2 sigma (at least 2: 5 taps). The truncated
// window is still smooth and symmetric, which is all the structure tensor needs, and OpenCV's
// default (+-4 sigma for float images) costs twice the taps: the blurs are most of a detection.
int GaussianHalfWidth(double sigma) {
  return std::max(2, static_cast<int>(std::lround(2.0 * sigma)));
}

// Index i of a row or column of n under OpenCV's default border (reflect-101: -1 -> 1,
// n -> n - 2), for any i: a window wider than the image reflects more than once.
int Reflect101(int i, int n) {
  if (n == 1) return 0;
  while (i < 0 || i >= n) i = i < 0 ? -i : 2 * (n - 1) - i;
  return i;
}

// std::lround of a float pixel coordinate, inline: the library call cost a tenth of merging a
// frame's corners. In double, x + 0.5 is exact for |x| < 2^28, so truncating it rounds halves
// away from zero exactly as lround does.
inline int RoundPixel(float x) {
  return x >= 0 ? static_cast<int>(static_cast<double>(x) + 0.5)
                : -static_cast<int>(0.5 - static_cast<double>(x));
}

// The largest value of a float row (no NaN), sixteen lanes at a time: a maximum is exact in
// any order, and the scalar form (std::max) is not vectorized by GCC and cost a tenth of
// HarrisRows. Always inlined into the clones, so each gets its own vector width: left to GCC,
// the grown HarrisRows called the baseline (SSE2) copy, a fifth of its time.
__attribute__((always_inline)) inline float RowMax(const float* row, int n) {
  float best = row[0];
  int x = 0;
  if (n >= 16) {
    Floats16 lanes;
    __builtin_memcpy(&lanes, row, sizeof lanes);
    for (x = 16; x + 16 <= n; x += 16) {
      Floats16 v;
      __builtin_memcpy(&v, row + x, sizeof v);
      lanes = v > lanes ? v : lanes;
    }
    for (int j = 0; j < 16; ++j) best = std::max(best, lanes[j]);
  }
  for (; x < n; ++x) best = std::max(best, row[x]);
  return best;
}

// 3x3 Sobel gradients (OpenCV's kernels: gx = [-1 0 1] across, [1 2 1] down) at column x of a
// row of the smoothed image, from its rows above and below; columns left and right of x are
// given, so the image's edges can pass reflected ones.
inline void SobelAt(const uint8_t* above, const uint8_t* row, const uint8_t* below, int left, int x,
                    int right, float* gx, float* gy) {
  *gx = static_cast<float>((above[right] - above[left]) + 2 * (row[right] - row[left]) +
                           (below[right] - below[left]));
  *gy = static_cast<float>((below[left] + 2 * below[x] + below[right]) -
                           (above[left] + 2 * above[x] + above[right]));
}

// The structure tensor's entries (gx^2, gy^2, gx gy) at columns [x0, x1) of a row of the
// smoothed image, interior columns (x0 >= 1, x1 < cols). The gradients are exact integers
// (|g| <= 1020), so the entries are too. Restricted pointers: the planes never overlap the image,
// which the vectorizer cannot otherwise know (8-bit pointers may alias anything).
inline void TensorEntries(const uint8_t* __restrict above, const uint8_t* __restrict row,
                          const uint8_t* __restrict below, int x0, int x1, float* __restrict xx,
                          float* __restrict yy, float* __restrict xy) {
  for (int x = x0; x < x1; ++x) {
    float gx, gy;
    SobelAt(above, row, below, x - 1, x, x + 1, &gx, &gy);
    xx[x] = gx * gx;
    yy[x] = gy * gy;
    xy[x] = gx * gy;
  }
}

// The tensor's entries of image row y, written to three planes of `padded` floats from column
// `half` on, with `half` reflected columns on either side for the window filter along the row.
inline void TensorRow(const cv::Mat& smoothed, int y, int half, int padded, float* planes) {
  const int rows = smoothed.rows, cols = smoothed.cols;
  const uint8_t* above = smoothed.ptr<uint8_t>(Reflect101(y - 1, rows));
  const uint8_t* row = smoothed.ptr<uint8_t>(y);
  const uint8_t* below = smoothed.ptr<uint8_t>(Reflect101(y + 1, rows));
  float* xx = planes + half;
  float* yy = planes + padded + half;
  float* xy = planes + 2 * padded + half;
  TensorEntries(above, row, below, 1, cols - 1, xx, yy, xy);
  for (int x : {0, cols - 1}) {
    float gx, gy;
    SobelAt(above, row, below, Reflect101(x - 1, cols), x, Reflect101(x + 1, cols), &gx, &gy);
    xx[x] = gx * gx;
    yy[x] = gy * gy;
    xy[x] = gx * gy;
  }
  for (float* plane : {xx, yy, xy}) {
    for (int j = 1; j <= half; ++j) {
      plane[-j] = plane[Reflect101(-j, cols)];
      plane[cols - 1 + j] = plane[Reflect101(cols - 1 + j, cols)];
    }
  }
}

constexpr int kMaxWindow = 41;  // Window taps: sigma up to 10 px (a 20 px scale at half size).

// HarrisRows's ring rows hold the three filtered tensor planes interleaved in blocks of kLanes
// columns (a vector's worth): block b is columns kLanes b ... of gx^2, then of gy^2, then of
// gx gy. A pixel then reads each ring row through one pointer at three fixed offsets.
constexpr int kLanes = 16;
constexpr int kBlockFloats = 3 * kLanes;

// The Harris response of the pixel at float `at` (block offset plus lane) of the ring rows whose
// window is rows[0 ... 2 half]; every response is summed in this order.
template <int kHalf>
__attribute__((always_inline)) inline float ResponseAt(const float* const* rows, int half,
                                                       const float* g, float k, float norm,
                                                       int at) {
  float sums[3];
  for (int c = 0; c < 3; ++c) {
    const int i = at + c * kLanes;
    float acc = g[0] * rows[half][i];
    for (int t = 1; t <= half; ++t) acc += g[t] * (rows[half - t][i] + rows[half + t][i]);
    sums[c] = acc;
  }
  const float trace = sums[0] + sums[1];
  return norm * (sums[0] * sums[1] - sums[2] * sums[2] - k * trace * trace);
}

// Harris response R = det(M) - k tr(M)^2 of the smoothed 8-bit image, M the structure tensor
// of 3x3 Sobel gradients weighted by the symmetric window `taps` (centre first, `half` + 1 of
// them), with reflect-101 borders at every stage as OpenCV's filters have; scaled by `norm`.
// Returns the largest response. Streamed: each image row's tensor entries are computed once and
// filtered along the row into a ring holding the last 2 half + 2 rows, and response rows are
// weighted sums down the ring, two at a time: the pair shares 2 half of its 2 half + 2 rows, so a
// pixel loads 3 (half + 1) values instead of 3 (2 half + 1) (the sums were bound by loads), and
// with the planes interleaved (kLanes) the pair's rows are one pointer each, which the registers
// hold. Only the response is image-sized. kHalf > 0 fixes `half` at compile time, so the tap
// loops unroll.
template <int kHalf>
VISLOC_SIMD_CLONES float HarrisRows(const cv::Mat& smoothed, const std::vector<float>& taps,
                                    float k, float norm, cv::Mat* response) {
  const int half = kHalf > 0 ? kHalf : static_cast<int>(taps.size()) - 1;
  const int rows = smoothed.rows, cols = smoothed.cols, window = 2 * half + 1;
  const int blocks = (cols + kLanes - 1) / kLanes, full_blocks = cols / kLanes;
  // Tensor planes cover whole blocks, so the filter along the row reads past the image's last
  // column into zeros (window <= kMaxWindow: HarrisResponse checks).
  const int padded = blocks * kLanes + 2 * half;
  const int slots = window + 1;  // The rows of a pair of output rows.
  const float* g = taps.data();
  std::vector<float> tensor(3 * static_cast<size_t>(padded), 0.0f);
  // Ring rows are whole blocks of 48 floats, so each starts on a cache line.
  CacheLineVector<float> ring(static_cast<size_t>(slots) * blocks * kBlockFloats);
  std::vector<int> ring_row(slots, -1);  // Image row each ring slot holds.
  response->create(rows, cols, CV_32F);
  float strongest = 0.0f;
  for (int y = 0; y < rows; y += 2) {
    const int pair = std::min(2, rows - y);    // Output rows y ... y + pair - 1.
    const float* window_rows[kMaxWindow + 1];  // Ring rows of image rows y - half + j.
    for (int j = 0; j < window + pair - 1; ++j) {
      // The rows a pair needs at once are distinct modulo their count, reflected ones included.
      const int image_row = Reflect101(y - half + j, rows), slot = image_row % slots;
      float* filtered = &ring[static_cast<size_t>(slot) * blocks * kBlockFloats];
      if (ring_row[slot] != image_row) {
        TensorRow(smoothed, image_row, half, padded, tensor.data());
        for (int b = 0; b < blocks; ++b) {
          for (int c = 0; c < 3; ++c) {
            const float* in = &tensor[c * static_cast<size_t>(padded) + half];
            float* out = filtered + b * kBlockFloats + c * kLanes;
            // The tensor and the ring never overlap.
#pragma GCC ivdep
            for (int lane = 0; lane < kLanes; ++lane) {
              const int x = b * kLanes + lane;
              float acc = g[0] * in[x];
              for (int t = 1; t <= half; ++t) acc += g[t] * (in[x - t] + in[x + t]);
              out[lane] = acc;
            }
          }
        }
        ring_row[slot] = image_row;
      }
      window_rows[j] = filtered;
    }
    const float* const* second = window_rows + 1;  // The window of output row y + 1.
    float* r0 = response->ptr<float>(y);
    float* r1 = pair == 2 ? response->ptr<float>(y + 1) : nullptr;
    for (int b = 0; b < blocks; ++b) {
      // The last block's columns past the image go to scratch, then its image columns out.
      float scratch[2][kLanes];
      float* out0 = b < full_blocks ? r0 + b * kLanes : scratch[0];
      float* out1 = b < full_blocks && r1 ? r1 + b * kLanes : scratch[1];
      // The ring and the response never overlap, which the vectorizer cannot otherwise know.
      if (pair == 2) {
#pragma GCC ivdep
        for (int lane = 0; lane < kLanes; ++lane) {
          out0[lane] = ResponseAt<kHalf>(window_rows, half, g, k, norm, b * kBlockFloats + lane);
          out1[lane] = ResponseAt<kHalf>(second, half, g, k, norm, b * kBlockFloats + lane);
        }
      } else {
#pragma GCC ivdep
        for (int lane = 0; lane < kLanes; ++lane) {
          out0[lane] = ResponseAt<kHalf>(window_rows, half, g, k, norm, b * kBlockFloats + lane);
        }
      }
      if (b >= full_blocks) {
        const int rest = cols - b * kLanes;
        std::memcpy(r0 + b * kLanes, scratch[0], rest * sizeof(float));
        if (r1) std::memcpy(r1 + b * kLanes, scratch[1], rest * sizeof(float));
      }
    }
    strongest = std::max(strongest, RowMax(r0, cols));
    if (r1) strongest = std::max(strongest, RowMax(r1, cols));
  }
  return strongest;
}

// The local maxima of row `mid` at columns [x0, x1) (no 8-neighbour exceeds them), as byte
// masks: `strong` where the response also reaches `threshold` (corner candidates), and, when
// given, `positive` where it is above zero (the finest scale's maxima that LocalizeAtFinestScale
// moves coarse corners to). One pass computes both, so the finest response is scanned once.
// The 3x3 maximum is separable: the column maxima of the three rows (`column_max`, scratch for
// columns x0 - 1 ... x1), then their maximum across; the pixel itself is in it, which changes
// nothing (v >= max(a, v) exactly when v >= a). Four comparisons a pixel instead of eight.
// Separate loops for the two masks, so that each one vectorizes.
VISLOC_SIMD_CLONES void LocalMaxima(const float* __restrict up, const float* __restrict mid,
                                    const float* __restrict down, int x0, int x1, float threshold,
                                    float* __restrict column_max, uint8_t* __restrict strong,
                                    uint8_t* __restrict positive) {
  for (int x = x0 - 1; x <= x1; ++x) column_max[x] = std::max(std::max(up[x], mid[x]), down[x]);
  if (positive == nullptr) {
    for (int x = x0; x < x1; ++x) {
      const float around = std::max(std::max(column_max[x - 1], column_max[x]), column_max[x + 1]);
      strong[x] = static_cast<uint8_t>((mid[x] >= threshold) & (mid[x] >= around));
    }
    return;
  }
  for (int x = x0; x < x1; ++x) {
    const float around = std::max(std::max(column_max[x - 1], column_max[x]), column_max[x + 1]);
    const bool is_max = mid[x] >= around;
    strong[x] = static_cast<uint8_t>((mid[x] >= threshold) & is_max);
    positive[x] = static_cast<uint8_t>((mid[x] > 0.0f) & is_max);
  }
}

constexpr int kFlagWord = 64;  // Candidate flags FlaggedColumns packs into a word.

// The 64 flags (0 or 1 bytes) from `flags` on as the bits of a word, flag i in bit i.
inline uint64_t PackFlags(const uint8_t* flags) {
  uint64_t bits = 0;
#if defined(__SSE2__)
  const __m128i zero = _mm_setzero_si128();
  for (int i = 0; i < kFlagWord; i += 16) {
    const __m128i v = _mm_loadu_si128(reinterpret_cast<const __m128i*>(flags + i));
    const uint64_t is_zero = static_cast<uint32_t>(_mm_movemask_epi8(_mm_cmpeq_epi8(v, zero)));
    bits |= (~is_zero & 0xFFFF) << i;
  }
#else
  for (int i = 0; i < kFlagWord; i += 8) {
    uint64_t word;
    std::memcpy(&word, flags + i, sizeof word);
    // Byte j's low bit to bit 56 + j of the product (the partial products never carry).
    bits |= (((word & 0x0101010101010101ull) * 0x0102040810204080ull) >> 56) << i;
  }
#endif
  return bits;
}

// The columns x in [x0, x1) whose flag is set (0 or 1 bytes, readable a word past x1), written
// to `columns` in increasing order (room for x1 - x0 + kFlagWord); returns their count. About
// 1% of pixels are candidates and where is unpredictable: a bit-by-bit scan mispredicted a
// branch about once a candidate. Here a word's first four set bits are written whether there
// are that many or not (a word holds less than one on average), so only words with more than
// four branch.
VISLOC_SIMD_CLONES int FlaggedColumns(const uint8_t* flags, int x0, int x1, int* columns) {
  constexpr int kUnconditional = 4;
  int count = 0;
  for (int base = x0; base < x1; base += kFlagWord) {
    uint64_t bits = PackFlags(flags + base);
    if (x1 - base < kFlagWord) bits &= (uint64_t{1} << (x1 - base)) - 1;
    const int set = __builtin_popcountll(bits);
    int* out = columns + count;
    for (int i = 0; i < kUnconditional; ++i) {
      // The top bit stands in once `bits` runs out (ctz of 0 is undefined); those entries lie
      // past `set`, where they are overwritten or ignored.
      out[i] = base + __builtin_ctzll(bits | (uint64_t{1} << 63));
      bits &= bits - 1;
    }
    for (int i = kUnconditional; i < set; ++i) {
      out[i] = base + __builtin_ctzll(bits);
      bits &= bits - 1;
    }
    count += set;
  }
  return count;
}

// The sub-pixel peak (x + ox, y + oy) of the response maximum at column x of row y (`mid`), from
// a separable quadratic fit to its 4-neighbours; each offset within half a pixel.
inline Eigen::Vector2f SubPixelPeak(const float* up, const float* mid, const float* down, int x,
                                    int y) {
  const float v = mid[x];
  const float dx = 0.5f * (mid[x + 1] - mid[x - 1]), dxx = mid[x + 1] - 2 * v + mid[x - 1];
  const float dy = 0.5f * (down[x] - up[x]), dyy = down[x] - 2 * v + up[x];
  const float ox = dxx < 0 ? std::clamp(-dx / dxx, -0.5f, 0.5f) : 0.0f;
  const float oy = dyy < 0 ? std::clamp(-dy / dyy, -0.5f, 0.5f) : 0.0f;
  return Eigen::Vector2f(x + ox, y + oy);
}

// Local maxima above `threshold` (no 8-neighbour is larger), refined to sub-pixel by a separable
// quadratic fit. The response may come from a level of the image pyramid `level_scale` times
// smaller than the image; positions are returned in full-resolution pixels (pixel centres:
// full-resolution pixels 2i and 2i+1 average into half-resolution pixel i, centred at 2i + 0.5).
// With `positive_maxima`, also every positive local maximum of the response, border included
// (an 8-bit mask of its size; LocalizeAtFinestScale reads it).
void FindMaxima(const cv::Mat& response, float threshold, double sigma, int border, int level_scale,
                std::vector<Keypoint>* out, cv::Mat* positive_maxima = nullptr) {
  const int rows = response.rows, cols = response.cols;
  const float offset = 0.5f * (level_scale - 1);
  border = std::max(border, 1);
  const int x0 = border, x1 = cols - border;
  // Rows and columns scanned: the candidates' range, or every interior pixel for the mask.
  const int scan_y0 = positive_maxima ? 1 : border;
  const int scan_y1 = positive_maxima ? rows - 1 : rows - border;
  const int scan_x0 = positive_maxima ? 1 : x0, scan_x1 = positive_maxima ? cols - 1 : x1;
  if (positive_maxima) {
    positive_maxima->create(rows, cols, CV_8UC1);
    positive_maxima->setTo(0);
  }
  if (scan_x1 <= scan_x0) return;
  // Padded by a word of zeros, so FlaggedColumns reads whole words.
  CacheLineVector<uint8_t> strong(cols + kFlagWord, 0);
  CacheLineVector<float> column_max(cols);
  std::vector<int> columns(cols + kFlagWord);
  for (int y = scan_y0; y < scan_y1; ++y) {
    const float* r = response.ptr<float>(y);
    const float* up = response.ptr<float>(y - 1);
    const float* down = response.ptr<float>(y + 1);
    LocalMaxima(up, r, down, scan_x0, scan_x1, threshold, column_max.data(), strong.data(),
                positive_maxima ? positive_maxima->ptr<uint8_t>(y) : nullptr);
    if (y < border || y >= rows - border) continue;
    const int count = FlaggedColumns(strong.data(), x0, x1, columns.data());
    for (int i = 0; i < count; ++i) {
      const int x = columns[i];
      Keypoint keypoint;
      keypoint.pixel = SubPixelPeak(up, r, down, x, y) * static_cast<float>(level_scale) +
                       Eigen::Vector2f::Constant(offset);
      keypoint.scale_px = static_cast<float>(sigma);
      keypoint.response = r[x];
      out->push_back(keypoint);
    }
  }
}

// Moves corners found at coarser scales to the nearest maximum of the finest scale's response
// within their scale (with its sub-pixel fit): a blurred corner's response peak is displaced
// from the physical corner by an amount that depends on the view, so coarse positions would
// slide as the camera approaches. Corners without a fine maximum nearby keep their position.
// `is_max` marks the fine response's positive local maxima (FindMaxima's mask): found once for
// the image rather than by a 3x3 test at every pixel of every coarse corner's window, since
// coarse corners are a thousand or more and their windows overlap.
void LocalizeAtFinestScale(const cv::Mat& fine_response, const cv::Mat& is_max,
                           std::vector<Keypoint>* keypoints, double finest_scale) {
  const int rows = fine_response.rows, cols = fine_response.cols;
  // Keypoint scales are floats: compared with the double, the finest scale's own keypoints
  // (1.2f > 1.2) would all be searched again, for nothing.
  const float finest = static_cast<float>(finest_scale);
  if (rows < 3 || cols < 3 ||
      std::none_of(keypoints->begin(), keypoints->end(),
                   [&](const Keypoint& k) { return k.scale_px > finest; })) {
    return;
  }
  for (Keypoint& k : *keypoints) {
    if (k.scale_px <= finest) continue;
    const int radius = std::max(1, RoundPixel(k.scale_px));
    const int cx = RoundPixel(k.pixel.x()), cy = RoundPixel(k.pixel.y());
    int best_x = -1, best_y = -1;
    double best_distance = 1e9;
    for (int y = std::max(1, cy - radius); y <= std::min(rows - 2, cy + radius); ++y) {
      const uint8_t* maxima = is_max.ptr<uint8_t>(y);
      for (int x = std::max(1, cx - radius); x <= std::min(cols - 2, cx + radius); ++x) {
        if (!maxima[x]) continue;
        const float ex = x - k.pixel.x(), ey = y - k.pixel.y();
        const double distance = ex * ex + ey * ey;  // Squared: only compared.
        if (distance < best_distance) {
          best_distance = distance;
          best_x = x;
          best_y = y;
        }
      }
    }
    if (best_x < 0) continue;
    k.pixel = SubPixelPeak(fine_response.ptr<float>(best_y - 1), fine_response.ptr<float>(best_y),
                           fine_response.ptr<float>(best_y + 1), best_x, best_y);
  }
}

// The keypoints strongest first; equal responses in the order given (a stable order, so the
// result never depends on the sort's implementation). Sorted as 64-bit keys, response bits then index: the
// responses are positive, so their IEEE bits order as they do.
std::vector<Keypoint> SortedByResponse(const std::vector<Keypoint>& keypoints) {
  std::vector<uint64_t> keys(keypoints.size());
  for (size_t i = 0; i < keypoints.size(); ++i) {
    keys[i] = DescendingKey(keypoints[i].response, static_cast<uint32_t>(i));
  }
  RadixSort(&keys);
  std::vector<Keypoint> sorted;
  sorted.reserve(keypoints.size());
  for (uint64_t key : keys) sorted.push_back(keypoints[static_cast<uint32_t>(key)]);
  return sorted;
}

// One bit per pixel of an image, with two columns of padding on either side and two rows above
// and below, so a disc of radius 2 is marked without clipping: an image's worth is a few tens
// of kilobytes, cleared and probed within the cache, where a byte per pixel is not.
class PixelDiscMask {
 public:
  explicit PixelDiscMask(const cv::Size& size)
      : words_per_row_((size.width + 4 + 63) / 64),
        words_(static_cast<size_t>(words_per_row_) * (size.height + 4), 0) {}

  bool Test(int x, int y) const {
    const int bit = x + 2;
    return (Row(y)[bit >> 6] >> (bit & 63)) & 1;
  }

  // Marks the disc of radius 2 around (x, y): dx^2 + dy^2 <= 5, 21 pixels.
  void MarkDisc(int x, int y) {
    for (int dy = -2; dy <= 2; ++dy) {
      const int reach = std::abs(dy) == 2 ? 1 : 2;
      SetRun(Row(y + dy), x + 2 - reach, 2 * reach + 1);
    }
  }

 private:
  uint64_t* Row(int y) { return &words_[static_cast<size_t>(y + 2) * words_per_row_]; }
  const uint64_t* Row(int y) const {
    return &words_[static_cast<size_t>(y + 2) * words_per_row_];
  }
  // Sets bits first ... first + length - 1 (length <= 5) of a row.
  static void SetRun(uint64_t* row, int first, int length) {
    const uint64_t run = (uint64_t{1} << length) - 1;
    const int word = first >> 6, shift = first & 63;
    row[word] |= run << shift;
    if (shift + length > 64) row[word + 1] |= run >> (64 - shift);
  }

  int words_per_row_;
  std::vector<uint64_t> words_;
};

// MergeAcrossScales a corner at a time, strongest first: whether a stronger corner kept already
// covers this one (then it goes), else it is kept and covers its own disc.
class CornerMerger {
 public:
  explicit CornerMerger(const cv::Size& size)
      : taken_(size), size_(size), max_x_(size.width - 0.5f), max_y_(size.height - 0.5f) {}

  bool Keep(const Keypoint& k) {
    // Rounding to a pixel of the image (the mask has no room beyond it); NaN fails too.
    VISLOC_CHECK(k.pixel.x() > -0.5f && k.pixel.x() < max_x_ && k.pixel.y() > -0.5f &&
                     k.pixel.y() < max_y_,
                 "a corner at (", k.pixel.x(), ", ", k.pixel.y(), ") lies outside the ",
                 size_.width, "x", size_.height, " image");
    const int x = RoundPixel(k.pixel.x()), y = RoundPixel(k.pixel.y());
    if (taken_.Test(x, y)) return false;
    taken_.MarkDisc(x, y);
    return true;
  }

 private:
  PixelDiscMask taken_;
  cv::Size size_;
  float max_x_, max_y_;
};

// OpenCV's 8-bit Gaussian kernel in fixed point (cv::GaussianBlur on CV_8U, OpenCV 4.x): the
// normalized Gaussian of `window` taps times 256, rounded with error diffusion from the outer
// taps inwards, the centre taking what makes the sum 256 (getGaussianKernelFixedPoint_ED over
// getGaussianKernelBitExact, with IEEE doubles for its soft doubles; every step there is
// correctly rounded but the exponential, which would have to land within an ulp of a rounding
// boundary to differ). The blur test holds it to OpenCV's on every scale a detector uses.
std::vector<uint16_t> FixedPointGaussianTaps(int window, double sigma) {
  const int half = window / 2;
  const double scale = -0.125 / (sigma * sigma);  // x below is twice the offset.
  std::vector<double> values(half);
  double sum = 0.0;
  for (int i = 0, x = 1 - window; i < half; ++i, x += 2) {
    values[i] = std::exp(static_cast<double>(x * x) * scale);
    sum += values[i];
  }
  sum *= 2.0;
  sum += 1.0;
  const double normalize = 1.0 / sum;
  std::vector<uint16_t> taps(window);
  double error = 0.0;
  int64_t total = 0;
  for (int i = 0; i < half; ++i) {
    const double adjusted = values[i] * normalize * 256.0 + error;
    const int64_t tap = std::llrint(adjusted);  // Half to even, as cvRound of a soft double.
    error = adjusted - static_cast<double>(tap);
    taps[i] = taps[window - 1 - i] = static_cast<uint16_t>(tap);
    total += tap;
  }
  taps[half] = static_cast<uint16_t>(256 - 2 * total);
  return taps;
}

// One row of GaussianBlur8u's filter along rows, out[x] = sum_t k[t] in[x + t], kept as floats
// for the filter down the columns. Sixteen-bit sums as OpenCV's: at most 255 * 256, and every
// partial sum of these non-negative terms is below the whole, so the symmetric grouping of the
// five-tap window is exact too. Restricted pointers: nothing here overlaps, which the
// vectorizer cannot otherwise know.
template <int kWindow>
inline void BlurAlongRow(const uint8_t* __restrict in, const uint16_t* __restrict k, int cols,
                         int window, float* __restrict out) {
  if constexpr (kWindow == 5) {
    const uint16_t k0 = k[0], k1 = k[1], k2 = k[2];
    for (int x = 0; x < cols; ++x) {
      const uint16_t outer = static_cast<uint16_t>(in[x] + in[x + 4]);
      const uint16_t inner = static_cast<uint16_t>(in[x + 1] + in[x + 3]);
      out[x] = static_cast<uint16_t>(k0 * outer + k1 * inner + k2 * in[x + 2]);
    }
  } else {
    for (int x = 0; x < cols; ++x) {
      uint32_t acc = 0;
      for (int t = 0; t < window; ++t) acc += uint32_t{k[t]} * in[x + t];
      out[x] = static_cast<float>(acc);
    }
  }
}

// One row of its filter down the columns, with the rounding, from the window's rows in[0 .. n -
// 1]. In floats, exactly: the products and every partial sum are integers below 255 * 256^2 <
// 2^24, and adding 2^15 and scaling by 2^-16 before truncating are exact as well.
template <int kWindow>
inline void BlurDownColumns(const float* const* in, const uint16_t* __restrict k, int cols,
                            int window, uint8_t* __restrict out) {
  if constexpr (kWindow == 5) {  // The detector's scales: each row a restricted pointer.
    const float* __restrict r0 = in[0];
    const float* __restrict r1 = in[1];
    const float* __restrict r2 = in[2];
    const float* __restrict r3 = in[3];
    const float* __restrict r4 = in[4];
    const float k0 = k[0], k1 = k[1], k2 = k[2];
    for (int x = 0; x < cols; ++x) {
      const float acc = k0 * (r0[x] + r4[x]) + k1 * (r1[x] + r3[x]) + k2 * r2[x];
      out[x] = static_cast<uint8_t>(static_cast<int>((acc + 32768.0f) * (1.0f / 65536.0f)));
    }
  } else {
    for (int x = 0; x < cols; ++x) {
      float acc = 0.0f;
      for (int t = 0; t < window; ++t) acc += static_cast<float>(k[t]) * in[t][x];
      out[x] = static_cast<uint8_t>(static_cast<int>((acc + 32768.0f) * (1.0f / 65536.0f)));
    }
  }
}

constexpr int kRowsAhead = 2;  // Image rows fetched ahead of the blur.

// cv::GaussianBlur of an 8-bit image with `taps` (FixedPointGaussianTaps) and OpenCV's default
// border (reflect-101), bit for bit: OpenCV sums sum_i taps_i p_i along the row exactly (8
// fraction bits, at most 255 * 256), then sum_j taps_j h_j down the column exactly (16 fraction
// bits) and rounds once, half up: out = (sum_j taps_j sum_i taps_i p + 2^15) >> 16. Exact sums
// do not depend on their order, so a streamed pass with its own loops (vectorized, in every
// clone) gives the same bytes. Rows are filtered once into a ring of the last `window`, as in
// HarrisRows. kWindow > 0 fixes the window at compile time.
template <int kWindow>
VISLOC_SIMD_CLONES void GaussianBlur8u(const cv::Mat& grey, const std::vector<uint16_t>& taps,
                                       cv::Mat* smoothed) {
  const int window = kWindow > 0 ? kWindow : static_cast<int>(taps.size());
  const int half = window / 2;
  const int rows = grey.rows, cols = grey.cols;
  std::vector<uint8_t> padded(cols + 2 * static_cast<size_t>(half));
  // Rows a whole number of cache lines apart, each starting on one.
  const int stride = (cols + kLanes - 1) / kLanes * kLanes;
  CacheLineVector<float> ring(static_cast<size_t>(window) * stride);
  std::vector<int> ring_row(window, -1);
  std::vector<const float*> rows_in_window(window);
  smoothed->create(rows, cols, CV_8UC1);
  for (int y = 0; y < rows; ++y) {
    for (int j = -half; j <= half; ++j) {
      const int image_row = Reflect101(y + j, rows), slot = image_row % window;
      float* filtered = &ring[static_cast<size_t>(slot) * stride];
      if (ring_row[slot] != image_row) {
        const uint8_t* in = grey.ptr<uint8_t>(image_row);
        // The image is read once, here, a row at a time, and often straight from memory (a
        // frame just received, or one of a benchmark's): asking for the row after next while
        // this one is filtered saved a twentieth of a KITTI detection.
        if (image_row + kRowsAhead < rows) {
          const uint8_t* ahead = grey.ptr<uint8_t>(image_row + kRowsAhead);
          for (size_t x = 0; x < static_cast<size_t>(cols); x += kCacheLineBytes) {
            __builtin_prefetch(ahead + x);
          }
        }
        std::memcpy(&padded[half], in, cols);
        for (int t = 1; t <= half; ++t) {
          padded[half - t] = in[Reflect101(-t, cols)];
          padded[half + cols - 1 + t] = in[Reflect101(cols - 1 + t, cols)];
        }
        BlurAlongRow<kWindow>(padded.data(), taps.data(), cols, window, filtered);
        ring_row[slot] = image_row;
      }
      rows_in_window[j + half] = filtered;
    }
    BlurDownColumns<kWindow>(rows_in_window.data(), taps.data(), cols, window,
                             smoothed->ptr<uint8_t>(y));
  }
}

}  // namespace

std::vector<Keypoint> MergeAcrossScales(std::vector<Keypoint> keypoints, const cv::Size& size) {
  CornerMerger merger(size);
  std::vector<Keypoint> kept;
  kept.reserve(keypoints.size());
  for (const Keypoint& k : SortedByResponse(keypoints)) {
    if (merger.Keep(k)) kept.push_back(k);
  }
  return kept;
}

void GaussianBlurLikeOpenCv(const cv::Mat& grey, double sigma, int half, cv::Mat* smoothed) {
  VISLOC_CHECK(grey.type() == CV_8UC1 && half >= 1, "8-bit blur, half width ", half);
  const int window = 2 * half + 1;
  if (grey.rows < window || grey.cols < window) {  // Reflected more than once: OpenCV's own.
    cv::GaussianBlur(grey, *smoothed, cv::Size(window, window), sigma);
    return;
  }
  const std::vector<uint16_t> taps = FixedPointGaussianTaps(window, sigma);
  if (window == 5) {
    GaussianBlur8u<5>(grey, taps, smoothed);
  } else {
    GaussianBlur8u<0>(grey, taps, smoothed);
  }
}

// The image is smoothed in 8-bit fixed point (OpenCV's arithmetic, GaussianBlurLikeOpenCv); the
// gradients and the tensor follow in one streamed pass (HarrisRows).
cv::Mat HarrisResponse(const cv::Mat& grey, double sigma, double k, float* max_response) {
  VISLOC_CHECK(grey.type() == CV_8UC1 && !grey.empty(),
               "the Harris response needs an 8-bit grey image");
  const int half = GaussianHalfWidth(sigma);
  VISLOC_CHECK(sigma > 0 && 2 * half + 1 <= kMaxWindow, "Harris scale ", sigma,
               " px: from 0 to 10 px");
  cv::Mat smoothed;
  const double derivative_sigma = 0.7 * sigma;
  const int derivative_half = GaussianHalfWidth(derivative_sigma);
  GaussianBlurLikeOpenCv(grey, derivative_sigma, derivative_half, &smoothed);
  const cv::Mat kernel = cv::getGaussianKernel(2 * half + 1, sigma, CV_32F);
  const std::vector<float> taps(kernel.ptr<float>(half), kernel.ptr<float>(half) + half + 1);
  // det - k trace^2, scale-normalized by sigma^4 (a product of two squared first derivatives)
  // so responses compare across scales; 1 / (8 * 255)^4 converts the integer gradients.
  const float norm = static_cast<float>(std::pow(sigma, 4) / std::pow(8.0 * 255.0, 4));
  const float kf = static_cast<float>(k);
  cv::Mat response;
  switch (half) {  // The windows of the default scales unrolled; others read `taps`.
    case 2:
      *max_response = HarrisRows<2>(smoothed, taps, kf, norm, &response);
      break;
    case 3:
      *max_response = HarrisRows<3>(smoothed, taps, kf, norm, &response);
      break;
    default:
      *max_response = HarrisRows<0>(smoothed, taps, kf, norm, &response);
  }
  return response;
}

std::vector<int> SelectEvenlyIndices(const std::vector<Keypoint>& keypoints,
                                     const cv::Size& image_size, int grid_cols, int grid_rows,
                                     int max_features) {
  std::vector<int> order(keypoints.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = static_cast<int>(i);
  if (static_cast<int>(keypoints.size()) <= max_features) return order;
  const auto stronger = [&](int a, int b) { return keypoints[a].response > keypoints[b].response; };
  if (!std::is_sorted(order.begin(), order.end(), stronger)) {
    std::sort(order.begin(), order.end(), stronger);
  }
  std::vector<Eigen::Vector2f> pixels;
  pixels.reserve(order.size());
  for (int i : order) pixels.push_back(keypoints[i].pixel);
  std::vector<int> selected =
      SpreadOverGrid(pixels, image_size, grid_cols, grid_rows, max_features);
  for (int& i : selected) i = order[i];
  return selected;
}

std::vector<Keypoint> HarrisSurf16Extractor::Detect(const cv::Mat& grey, int* detected) const {
  // A two-level pyramid: a scale whose sigma is at least 2 px is computed on the half-size
  // image with half the sigma (a quarter of the pixels, shorter kernels). The sigma^4
  // normalization makes the response independent of the level, and every corner is then
  // re-localized on the finest full-resolution response anyway.
  cv::Mat half;
  // The half-size image only when a scale uses it (queries detect at the finest scale only).
  if (*std::max_element(options_.scales_px.begin(), options_.scales_px.end()) >= 2.0) {
    cv::resize(grey, half, cv::Size(grey.cols / 2, grey.rows / 2), 0, 0, cv::INTER_AREA);
  }
  std::vector<cv::Mat> responses;
  std::vector<int> level_scales;
  float strongest = 0.0f;
  for (double sigma : options_.scales_px) {
    const int level_scale = sigma >= 2.0 ? 2 : 1;
    level_scales.push_back(level_scale);
    float max_response = 0.0f;
    responses.push_back(HarrisResponse(level_scale == 1 ? grey : half, sigma / level_scale,
                                       options_.harris_k, &max_response));
    strongest = std::max(strongest, max_response);
  }
  const float threshold =
      std::max(1e-12f, static_cast<float>(options_.relative_threshold) * strongest);
  const size_t finest = std::min_element(options_.scales_px.begin(), options_.scales_px.end()) -
                        options_.scales_px.begin();
  VISLOC_CHECK(level_scales[finest] == 1, "the finest scale must be below 2 px");
  // The finest scale's maxima, found with its candidates, when coarser scales will need them.
  cv::Mat fine_maxima;
  const bool coarse_scales = responses.size() > 1;
  std::vector<Keypoint> keypoints;
  const int border = std::max(options_.border_px, 2);
  for (size_t i = 0; i < responses.size(); ++i) {
    FindMaxima(responses[i], threshold, options_.scales_px[i], border / level_scales[i],
               level_scales[i], &keypoints, coarse_scales && i == finest ? &fine_maxima : nullptr);
  }
  if (coarse_scales) {
    LocalizeAtFinestScale(responses[finest], fine_maxima, &keypoints, options_.scales_px[finest]);
  }
  return MergeAndSelect(keypoints, grey.size(), detected);
}

// MergeAcrossScales, the cell threshold, then SelectEvenlyIndices's choice, in one pass over the
// candidates strongest first (a few thousand a frame, of which 600 are kept). A cell's
// strongest corner is the first one kept there, so the threshold is known when the next comes.
std::vector<Keypoint> HarrisSurf16Extractor::MergeAndSelect(const std::vector<Keypoint>& candidates,
                                                            const cv::Size& size,
                                                            int* detected) const {
  const std::vector<Keypoint> sorted = SortedByResponse(candidates);
  CornerMerger merger(size);
  GridSpread spread(size, options_.grid_cols, options_.grid_rows, options_.max_features);
  std::vector<float> cell_strongest(options_.grid_cols * options_.grid_rows, -1.0f);  // -1: none.
  std::vector<int> kept;  // Indices into `sorted`.
  kept.reserve(sorted.size());
  for (int i = 0; i < static_cast<int>(sorted.size()); ++i) {
    const Keypoint& k = sorted[i];
    if (!merger.Keep(k)) continue;
    const int cell = spread.Cell(k.pixel);
    if (cell_strongest[cell] < 0) cell_strongest[cell] = k.response;
    if (k.response < options_.cell_relative_threshold * cell_strongest[cell]) continue;
    kept.push_back(i);
    spread.Offer(i, cell);
  }
  if (detected) *detected = static_cast<int>(kept.size());
  std::vector<Keypoint> selected;
  const bool all = static_cast<int>(kept.size()) <= options_.max_features;
  for (int i : all ? kept : spread.Chosen()) selected.push_back(sorted[i]);
  return selected;
}

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

FeatureSet HarrisSurf16Extractor::Extract(const cv::Mat& grey, ExtractStats* stats) const {
  VISLOC_CHECK(grey.type() == CV_8UC1 && !grey.empty(), "features need an 8-bit grey image");
  Timer timer;
  FeatureSet features;
  int detected = 0;
  features.keypoints = Detect(grey, &detected);
  const double detect_ms = timer.ElapsedMs();
  timer.Restart();
  features.descriptors = Describe(grey, features.keypoints);
  if (stats) {
    stats->detect_ms = detect_ms;
    stats->describe_ms = timer.ElapsedMs();
    stats->detected = detected;
  }
  return features;
}

}  // namespace visloc
