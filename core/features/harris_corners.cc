// Harris-SURF16 detection, from responses to corners: local maxima with sub-pixel peaks,
// re-localization at the finest scale, the merge across scales, the per-cell threshold and the
// even spread over the grid (harris_surf16.h).
#include "core/features/harris_surf16.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>

#include <opencv2/imgproc.hpp>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "core/util/check.h"
#include "core/util/cpu_dispatch.h"
#include "core/util/memory.h"
#include "core/util/radix_sort.h"

namespace visloc {

namespace {


// std::lround of a float pixel coordinate, inline: the library call cost a tenth of merging a
// frame's corners. In double, x + 0.5 is exact for |x| < 2^28, so truncating it rounds halves
// away from zero exactly as lround does.
inline int RoundPixel(float x) {
  return x >= 0 ? static_cast<int>(static_cast<double>(x) + 0.5)
                : -static_cast<int>(0.5 - static_cast<double>(x));
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
  // More than the budget: the spread's choice (a ternary of the two would copy `kept`).
  if (static_cast<int>(kept.size()) > options_.max_features) kept = spread.Chosen();
  std::vector<Keypoint> selected;
  selected.reserve(kept.size());
  for (int i : kept) selected.push_back(sorted[i]);
  return selected;
}

}  // namespace visloc
