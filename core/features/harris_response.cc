// Harris-SURF16 detection, its first stage: the 8-bit Gaussian blur (OpenCV's fixed-point
// arithmetic, byte for byte) and the Harris response of the structure tensor (harris_surf16.h).
#include "core/features/harris_surf16.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>

#include <opencv2/imgproc.hpp>

#include "core/util/check.h"
#include "core/util/cpu_dispatch.h"
#include "core/util/memory.h"

namespace visloc {

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

}  // namespace visloc
