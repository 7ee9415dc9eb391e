#include "mapping/stereo_frame.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>

#include "core/util/check.h"
#include "core/util/cpu_dispatch.h"
#include "core/util/parallel.h"
#include "core/util/timer.h"

namespace visloc::mapping {

void StereoMatchOptions::Check() const {
  VISLOC_CHECK(min_depth_m > 0 && min_disparity_px > 0, "stereo range: depth from ", min_depth_m,
               " m, disparity from ", min_disparity_px, " px");
  VISLOC_CHECK(
      patch_radius_px >= 1 && min_zncc > 0 && min_zncc < 1 && uniqueness > 0 && uniqueness <= 1,
      "stereo correlation: radius ", patch_radius_px, " px, ZNCC ", min_zncc, ", uniqueness ",
      uniqueness);
  VISLOC_CHECK(refine_patch_radius_px >= 0 && refine_max_shift_px > 0, "disparity refinement ",
               refine_patch_radius_px, " px, ", refine_max_shift_px, " px");
  VISLOC_CHECK(threads >= 0, "stereo matching threads: ", threads, " (0: every core)");
}

namespace {

// Cell of the frames' keypoint grids; radius searches of any size visit the cells they touch.
constexpr int kGridCellPx = 16;
// Keypoints a thread searches at a time (BuildStereoFrame): small enough to share the work out
// evenly, large enough that taking the next is nothing beside searching them.
constexpr int kSearchChunk = 32;

// out[i] = the bilinear sample of rows `r0` and `r1` (the one below, both `width` long) at
// column row_start + (i - radius) * stride, `fy` of the way down, i in [0, 2 radius]: a patch's
// samples of one image row share the rows and their weight. Eight at a time, each lane the same
// IEEE operations as one sample alone. Every column must lie in [0, width - 2) (the caller
// bounds them), so truncation is the floor. A stride near 1 (the template's is 1) puts the eight
// at consecutive pixels: loaded as vectors, not gathered one by one.
inline void SampleRow(const float* r0, const float* r1, int width, float fy, double row_start,
                      double stride, int radius, float* out) {
  const int count = 2 * radius + 1;
  for (int first = 0; first < count; first += 8) {
    const int lanes = std::min(8, count - first);
    Doubles8 u;  // Lanes past the row repeat its last column: in bounds, never stored.
    for (int j = 0; j < 8; ++j) u[j] = std::min(first + j, count - 1) - radius;
    const Doubles8 column = row_start + u * stride;
    const Int64s8 x0 = __builtin_convertvector(column, Int64s8);
    const Floats8 fx =
        __builtin_convertvector(column - __builtin_convertvector(x0, Doubles8), Floats8);
    bool consecutive = x0[0] + 8 < width;  // All nine columns a vector load reads.
    for (int j = 1; j < lanes; ++j) consecutive &= x0[j] == x0[0] + j;
    Floats8 a, b, c, d;
    if (consecutive) {
      std::memcpy(&a, r0 + x0[0], sizeof(a));
      std::memcpy(&b, r0 + x0[0] + 1, sizeof(b));
      std::memcpy(&c, r1 + x0[0], sizeof(c));
      std::memcpy(&d, r1 + x0[0] + 1, sizeof(d));
    } else {
      for (int j = 0; j < 8; ++j) {
        a[j] = r0[x0[j]];
        b[j] = r0[x0[j] + 1];
        c[j] = r1[x0[j]];
        d[j] = r1[x0[j] + 1];
      }
    }
    const Floats8 value =
        (1.0f - fy) * ((1.0f - fx) * a + fx * b) + fy * ((1.0f - fx) * c + fx * d);
    for (int j = 0; j < lanes; ++j) out[first + j] = value[j];
  }
}

// J^T J of the three Jacobian columns, each entry summed in double in pixel order as six separate
// sums would be (the same bits), in one pass: the six sums' additions overlap rather than wait
// on each other.
inline Eigen::Matrix3d NormalMatrix(const float* j0, const float* j1, const float* j2, int n) {
  double s00 = 0, s10 = 0, s11 = 0, s20 = 0, s21 = 0, s22 = 0;
  for (int k = 0; k < n; ++k) {
    const double a = j0[k], b = j1[k], c = j2[k];
    s00 += a * a;
    s10 += b * a;
    s11 += b * b;
    s20 += c * a;
    s21 += c * b;
    s22 += c * c;
  }
  Eigen::Matrix3d jtj;
  jtj << s00, s10, s20, s10, s11, s21, s20, s21, s22;
  return jtj;
}

// Per-thread scratch of RefineDisparity, one entry per patch pixel: a map build refines hundreds
// of patches a frame.
struct RefinementScratch {
  Eigen::ArrayXf template_values;                  // Zero mean.
  Eigen::ArrayXf jacobian0, jacobian1, jacobian2;  // Columns of the Jacobian.
  Eigen::ArrayXf values;                           // The right image under the current warp.
  Eigen::ArrayXf residuals;                        // Zero-mean values minus the template.
  void Resize(int n) {
    for (Eigen::ArrayXf* a :
         {&template_values, &jacobian0, &jacobian1, &jacobian2, &values, &residuals}) {
      a->resize(n);
    }
  }
};

}  // namespace

// Built for AVX2 and AVX-512 too: there std::floor is one instruction, not a call (the same
// values).
VISLOC_SIMD_CLONES bool RefineDisparity(const cv::Mat& left, const cv::Mat& left_gradient_x,
                                        const cv::Mat& right, double x, double y, int radius,
                                        double* d) {
  const int margin = radius + 2;
  if (x < margin || y < margin || x >= left.cols - margin || y >= left.rows - margin) return false;
  const int n = (2 * radius + 1) * (2 * radius + 1);
  thread_local RefinementScratch scratch;
  scratch.Resize(n);
  // Disparity varies across the patch on slanted surfaces (the floor, the ceiling), so it is
  // modelled as d(u, v) = d0 + gu u + gv v over patch offsets (u, v); d0 is the disparity at the
  // patch centre. A pure shift would absorb the gradient as a bias. The patch offset (u, v) is
  // seen in the right image at column x + u - d(u, v) of row y + v: an affine warp of the patch
  // whose first row is (1 - gu, -gv, -d0).
  //
  // Inverse compositional Gauss-Newton (Baker and Matthews, IJCV 2004) on the zero-mean SSD: the
  // Jacobian is the template's (the left patch's) at the identity warp, so it and the normal
  // equations are made once, and an iteration samples the right image alone (the forward
  // additive form sampled the right image's gradient too and solved its normal equations each
  // time: half of a map build's time).
  const int side = 2 * radius + 1;
  for (int v = -radius, k = 0; v <= radius; ++v, k += side) {
    const double row_y = y + v;
    const int y0 = static_cast<int>(std::floor(row_y));
    const float fy = static_cast<float>(row_y - y0);
    SampleRow(left.ptr<float>(y0), left.ptr<float>(y0 + 1), left.cols, fy, x, 1.0, radius,
              &scratch.template_values[k]);
    float* gradient = &scratch.jacobian0[k];
    SampleRow(left_gradient_x.ptr<float>(y0), left_gradient_x.ptr<float>(y0 + 1), left.cols, fy, x,
              1.0, radius, gradient);
    for (int u = -radius; u <= radius; ++u) {
      // dT(W(u, v; p))/dp at p = 0: the template's x gradient times dx/dp = (-1, -u, -v).
      const float g = gradient[u + radius];
      scratch.jacobian1[k + u + radius] = -g * static_cast<float>(u);
      scratch.jacobian2[k + u + radius] = -g * static_cast<float>(v);
      gradient[u + radius] = -g;
    }
  }
  scratch.template_values -= scratch.template_values.mean();
  Eigen::Matrix3d jtj =
      NormalMatrix(scratch.jacobian0.data(), scratch.jacobian1.data(), scratch.jacobian2.data(), n);
  if (jtj(0, 0) < 1e-9) return false;  // A flat patch along the row: nothing to align.
  jtj.diagonal() += Eigen::Vector3d(0, 1e-3, 1e-3) * jtj(0, 0);  // gradients small unless needed
  const Eigen::LDLT<Eigen::Matrix3d> normal_equations(jtj);
  const int y0 = static_cast<int>(std::floor(y));
  const float fy = static_cast<float>(y - y0);
  double d0 = *d, gu = 0.0, gv = 0.0;
  for (int iteration = 0; iteration < 10; ++iteration) {
    for (int v = -radius, k = 0; v <= radius; ++v, k += side) {
      const float* row = right.ptr<float>(y0 + v);
      const float* next_row = right.ptr<float>(y0 + v + 1);
      const double row_start = x - d0 - gv * v;
      // The row's columns grow with u (1 - gu >= 0: each step divides it by a positive factor),
      // so its two ends bound them all; the samples between need no test, and vectorize.
      const double stride = 1.0 - gu;
      if (row_start - radius * stride < 1 || row_start + radius * stride >= right.cols - 2) {
        return false;
      }
      SampleRow(row, next_row, right.cols, fy, row_start, stride, radius, &scratch.values[k]);
    }
    // r = (I_r(W(u, v; p)) - mean_r) - (T - mean_T): small numbers, summed in floats.
    Eigen::ArrayXf& residuals = scratch.residuals;  // Allocated once per thread, not per step.
    residuals = scratch.values - scratch.values.mean() - scratch.template_values;
    const Eigen::Vector3d jtr((scratch.jacobian0 * residuals).sum(),
                              (scratch.jacobian1 * residuals).sum(),
                              (scratch.jacobian2 * residuals).sum());
    // The template warped by the step matches the right image where T + J step = I_r.
    const Eigen::Vector3d step = normal_equations.solve(jtr);
    if (!step.allFinite() || std::abs(step[1]) >= 0.5) return false;
    // W(p) <- W(p) o W(step)^-1, composing the warps' first rows (1 - gu, -gv, -d0).
    const double a = 1.0 - gu, step_a = 1.0 - step[1];
    d0 -= a * step[0] / step_a;
    gv -= a * step[2] / step_a;
    gu = 1.0 - a / step_a;
    if (std::abs(step[0]) < 5e-3) break;
  }
  if (std::abs(gu) > 0.5 || std::abs(gv) > 0.5) return false;  // not a surface
  *d = d0;
  return true;
}

// The rectified pair on the canvas (StereoRectifier::Rectify), as the correlation search and the
// refinement need them.
struct RectifiedPair {
  cv::Mat left, right;                     // 8-bit.
  cv::Mat left_f, left_gradient, right_f;  // CV_32F, for the refinement.
  cv::Mat right_sum, right_sum_sq;         // Integral images of `right` (CV_32S, CV_64F).
};

namespace {

RectifiedPair Rectify(const cv::Mat& left_raw, const cv::Mat& right_raw,
                      const StereoRectifier& rectifier, bool refine) {
  RectifiedPair pair;
  rectifier.Rectify(left_raw, right_raw, &pair.left, &pair.right);
  cv::integral(pair.right, pair.right_sum, pair.right_sum_sq, CV_32S, CV_64F);
  if (refine) {
    pair.left.convertTo(pair.left_f, CV_32F);
    pair.right.convertTo(pair.right_f, CV_32F);
    // Central difference, as the alignment's linearization assumes.
    const cv::Mat kernel = (cv::Mat_<float>(1, 3) << -0.5f, 0.0f, 0.5f);
    cv::filter2D(pair.left_f, pair.left_gradient, CV_32F, kernel, cv::Point(-1, -1), 0,
                 cv::BORDER_REPLICATE);
  }
  return pair;
}

// sums[k] += value * right[k] for k in [0, count): one left pixel against a run of the right row.
VISLOC_SIMD_CLONES void AccumulateProducts(int value, const uchar* __restrict right, int count,
                                           int* __restrict sums) {
  for (int k = 0; k < count; ++k) sums[k] += value * right[k];
}

// The best integer disparity of the left patch centred at canvas pixel (x, y), by ZNCC along the
// right image's row over [d_min, d_max], with its sub-pixel offset from a parabola through the
// neighbouring correlations. Returns false (and counts why) when none is strong and unique.
bool SearchRow(const RectifiedPair& pair, int x, int y, int d_min, int d_max,
               const StereoMatchOptions& options, std::vector<double>* scores, double* disparity,
               StereoMatchStats* stats) {
  const int r = options.patch_radius_px, side = 2 * r + 1, n = side * side;
  double left_sum = 0, left_sum_sq = 0;
  for (int v = -r; v <= r; ++v) {
    const uchar* row = pair.left.ptr<uchar>(y + v) + x;
    for (int u = -r; u <= r; ++u) {
      left_sum += row[u];
      left_sum_sq += row[u] * row[u];
    }
  }
  const double left_var = left_sum_sq - left_sum * left_sum / n;
  if (left_var < n) {  // Flat: less than one grey level of deviation per pixel.
    ++stats->weak;
    return false;
  }
  // The cross products of every disparity first, pixel by pixel of the left patch: for one left
  // pixel they run along the right row, contiguous in reversed disparity (cross[k] is disparity
  // d_max - k), which vectorizes. Exact integers: the same sums as disparity by disparity.
  const int count = d_max - d_min + 1;
  thread_local std::vector<int> cross;
  cross.assign(count, 0);
  int* sums = cross.data();
  for (int v = -r; v <= r; ++v) {
    const uchar* a = pair.left.ptr<uchar>(y + v) + x;
    const uchar* row = pair.right.ptr<uchar>(y + v) + x - d_max;
    for (int u = -r; u <= r; ++u) {
      AccumulateProducts(a[u], row + u, count, sums);
    }
  }
  scores->assign(count, -1.0);
  int best = -1;
  for (int d = d_min; d <= d_max; ++d) {
    const int xr = x - d;
    const int x0 = xr - r, y0 = y - r;
    const double right_sum = pair.right_sum.at<int>(y0 + side, x0 + side) -
                             pair.right_sum.at<int>(y0, x0 + side) -
                             pair.right_sum.at<int>(y0 + side, x0) + pair.right_sum.at<int>(y0, x0);
    const double right_sum_sq = pair.right_sum_sq.at<double>(y0 + side, x0 + side) -
                                pair.right_sum_sq.at<double>(y0, x0 + side) -
                                pair.right_sum_sq.at<double>(y0 + side, x0) +
                                pair.right_sum_sq.at<double>(y0, x0);
    const double right_var = right_sum_sq - right_sum * right_sum / n;
    if (right_var < n) continue;
    const int product = cross[d_max - d];
    const double score = (product - left_sum * right_sum / n) / std::sqrt(left_var * right_var);
    (*scores)[d - d_min] = score;
    if (best < 0 || score > (*scores)[best - d_min]) best = d;
  }
  if (best < 0 || (*scores)[best - d_min] < options.min_zncc) {
    ++stats->weak;
    return false;
  }
  const double top = (*scores)[best - d_min];
  double second = -1.0;
  for (int d = d_min; d <= d_max; ++d) {
    if (std::abs(d - best) > 1) second = std::max(second, (*scores)[d - d_min]);
  }
  if (1.0 - top > options.uniqueness * (1.0 - second)) {
    ++stats->ambiguous;
    return false;
  }
  double offset = 0.0;
  if (best > d_min && best < d_max) {
    const double before = (*scores)[best - 1 - d_min], after = (*scores)[best + 1 - d_min];
    const double curvature = before - 2 * top + after;
    if (curvature < 0) offset = std::clamp(0.5 * (before - after) / curvature, -0.5, 0.5);
  }
  *disparity = best + offset;
  return true;
}

// The keypoints the rectified camera sees, on the canvas, with their rectified positions: a
// fisheye's rim lies beyond any pinhole view (mapping works in rectified coordinates).
FeatureSet KeepRectifiable(FeatureSet features, const StereoRectifier& rectifier,
                           std::vector<Eigen::Vector2d>* rectified) {
  const Eigen::Vector2d low = -rectifier.canvas_offset_px();
  const Eigen::Vector2d high =
      low + Eigen::Vector2d(rectifier.canvas_size().width - 1, rectifier.canvas_size().height - 1);
  std::vector<int> kept;
  rectified->clear();
  for (size_t i = 0; i < features.size(); ++i) {
    const Eigen::Vector2d p =
        rectifier.RectifyLeftPixel(features.keypoints[i].pixel.cast<double>());
    if (!p.allFinite() || (p.array() < low.array()).any() || (p.array() > high.array()).any()) {
      continue;
    }
    kept.push_back(static_cast<int>(i));
    rectified->push_back(p);
  }
  return kept.size() == features.size() ? std::move(features) : features.Subset(kept);
}

// Records keypoint i's stereo match at `disparity` (rectified px, corrected), or counts it out of
// range.
void SetDisparity(const StereoRectifier& rectifier, const StereoMatchOptions& options, size_t i,
                  double disparity, StereoFrame* frame) {
  const Camera& rect = rectifier.rectified_camera();
  const double f = rect.fx(), baseline = rectifier.baseline_m();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  if (disparity < options.min_disparity_px || disparity > f * baseline / options.min_depth_m) {
    frame->right_x_rect[i] = nan;
    frame->point_in_rect[i] = Eigen::Vector3d::Constant(nan);
    ++frame->stats.out_of_range;
    return;
  }
  const Eigen::Vector2d& l = frame->left_rect[i];
  const double z = f * baseline / disparity;
  frame->right_x_rect[i] = l.x() - disparity;
  frame->point_in_rect[i] =
      Eigen::Vector3d((l.x() - rect.cx()) * z / f, (l.y() - rect.cy()) * z / rect.fy(), z);
  ++frame->stats.matched;
}

}  // namespace

void CorrectStereoFrame(const DisparityCorrection& change, const StereoRectifier& rectifier,
                        const StereoMatchOptions& options, StereoFrame* frame) {
  const Camera& rect = rectifier.rectified_camera();
  frame->stats.matched = 0;
  for (size_t i = 0; i < frame->right_x_rect.size(); ++i) {
    const double right_x = frame->right_x_rect[i];
    if (!std::isfinite(right_x)) continue;
    const double disparity =
        frame->left_rect[i].x() - right_x - change.BiasPx(right_x, rect.fx(), rect.cx());
    SetDisparity(rectifier, options, i, disparity, frame);
  }
}

namespace {

// The disparity (rectified px, uncorrected) of the left keypoint at rectified `l`, or NaN with the
// reason counted in `stats`. `scores` is the caller's scratch.
double MatchKeypoint(const RectifiedPair& pair, const StereoRectifier& rectifier,
                     const StereoMatchOptions& options, const Eigen::Vector2d& l,
                     std::vector<double>* scores, StereoMatchStats* stats) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double max_disparity =
      rectifier.rectified_camera().fx() * rectifier.baseline_m() / options.min_depth_m;
  // Patches must lie inside the canvas, and refinement needs a margin of its own.
  const int margin = std::max(options.patch_radius_px, options.refine_patch_radius_px + 2) + 1;
  const Eigen::Vector2d c = l + rectifier.canvas_offset_px();  // On the canvas.
  const int x = static_cast<int>(std::lround(c.x())), y = static_cast<int>(std::lround(c.y()));
  if (y < margin || y >= pair.left.rows - margin || x >= pair.left.cols - margin) return nan;
  const int d_min = static_cast<int>(std::floor(options.min_disparity_px));
  const int d_max = std::min(static_cast<int>(std::ceil(max_disparity)), x - margin);
  if (d_max < d_min + 2) return nan;
  ++stats->searched;
  double disparity = 0;
  if (!SearchRow(pair, x, y, d_min, d_max, options, scores, &disparity, stats)) return nan;
  // The correlation ran at the nearest whole pixel; the keypoint a fraction of a pixel beside
  // it shares its disparity (the refinement below measures it at the keypoint itself).
  if (options.refine_patch_radius_px > 0) {
    double refined = disparity;
    if (!RefineDisparity(pair.left_f, pair.left_gradient, pair.right_f, c.x(), c.y(),
                         options.refine_patch_radius_px, &refined) ||
        std::abs(refined - disparity) > options.refine_max_shift_px) {
      ++stats->refine_rejected;
      return nan;
    }
    disparity = refined;
  }
  return disparity;
}

void AddSearchCounts(const StereoMatchStats& part, StereoMatchStats* total) {
  total->searched += part.searched;
  total->weak += part.weak;
  total->ambiguous += part.ambiguous;
  total->refine_rejected += part.refine_rejected;
}

}  // namespace

StereoFrameSearch::StereoFrameSearch(const cv::Mat& left_raw, const cv::Mat& right_raw,
                                     const FeatureExtractor& extractor,
                                     const StereoRectifier& rectifier,
                                     const StereoMatchOptions& options,
                                     const DisparityCorrection& correction)
    : rectifier_(&rectifier),
      options_(options),
      correction_(correction),
      pair_(std::make_unique<RectifiedPair>()) {
  const Timer timer;
  options.Check();
  RunBoth(
      ResolveThreads(options.threads),
      [&] {
        frame_.left = KeepRectifiable(extractor.Extract(left_raw), rectifier, &frame_.left_rect);
      },
      [&] {
        *pair_ = Rectify(left_raw, right_raw, rectifier, options.refine_patch_radius_px > 0);
      });
  const Camera& rect = rectifier.rectified_camera();
  const size_t n = frame_.left.size();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  frame_.right_x_rect.assign(n, nan);
  frame_.point_in_rect.assign(n, Eigen::Vector3d::Constant(nan));
  frame_.stats.keypoints = static_cast<int>(n);
  std::vector<Eigen::Vector2f> grid_pixels(n);
  for (size_t i = 0; i < n; ++i) grid_pixels[i] = frame_.left_rect[i].cast<float>();
  frame_.grid = KeypointGrid(std::move(grid_pixels), rect.width(), rect.height(), kGridCellPx);
  searched_.assign(n, false);
  prepare_ms_ = timer.ElapsedMs();
}

StereoFrameSearch::StereoFrameSearch(StereoFrame complete)
    : frame_(std::move(complete)), searched_count_(static_cast<int>(frame_.left.size())) {}

StereoFrameSearch::~StereoFrameSearch() = default;
StereoFrameSearch::StereoFrameSearch(StereoFrameSearch&&) noexcept = default;
StereoFrameSearch& StereoFrameSearch::operator=(StereoFrameSearch&&) noexcept = default;

void StereoFrameSearch::SetCorrection(const DisparityCorrection& correction) {
  VISLOC_CHECK(searched_count_ == 0, "a frame's disparity correction is set before its searches");
  correction_ = correction;
}

namespace {

// The disparities (rectified px, uncorrected; NaN: none) of the keypoints at rectified
// `left_rect[todo[j]]`, j in [0, todo.size()), and each search's counts in (*stats)[j]; in chunks
// the threads take as they finish: a keypoint's search is as long as its row's disparity range,
// which grows across the image, so equal halves were not equal work.
std::vector<double> MatchKeypoints(const RectifiedPair& pair, const StereoRectifier& rectifier,
                                   const StereoMatchOptions& options,
                                   const std::vector<Eigen::Vector2d>& left_rect,
                                   const std::vector<int>& todo,
                                   std::vector<StereoMatchStats>* stats) {
  std::vector<double> disparities(todo.size(), std::numeric_limits<double>::quiet_NaN());
  stats->assign(todo.size(), StereoMatchStats{});
  ParallelChunks(static_cast<int>(todo.size()), ResolveThreads(options.threads), kSearchChunk,
                 [&](int begin, int end) {
                   std::vector<double> scores;
                   for (int j = begin; j < end; ++j) {
                     disparities[j] = MatchKeypoint(pair, rectifier, options, left_rect[todo[j]],
                                                    &scores, &(*stats)[j]);
                   }
                 });
  return disparities;
}

}  // namespace

void StereoFrameSearch::SearchAhead() {
  VISLOC_CHECK(searched_count_ == 0 && ahead_disparity_.empty(),
               "a frame's searches run ahead before any is made");
  if (!pair_) return;
  const Timer timer;
  std::vector<int> all(frame_.left.size());
  for (size_t i = 0; i < all.size(); ++i) all[i] = static_cast<int>(i);
  ahead_disparity_ =
      MatchKeypoints(*pair_, *rectifier_, options_, frame_.left_rect, all, &ahead_stats_);
  pair_.reset();
  prepare_ms_ += timer.ElapsedMs();
}

void StereoFrameSearch::Search(const std::vector<int>& features) {
  if (searched_.empty()) return;  // Built complete, or no keypoints.
  const Timer timer;
  std::vector<int> todo;
  for (int i : features) {
    if (!searched_[i]) {
      searched_[i] = true;
      todo.push_back(i);
    }
  }
  if (todo.empty()) return;
  searched_count_ += static_cast<int>(todo.size());
  std::vector<double> disparities;
  if (ahead_disparity_.empty()) {
    std::vector<StereoMatchStats> stats;
    disparities = MatchKeypoints(*pair_, *rectifier_, options_, frame_.left_rect, todo, &stats);
    for (const StereoMatchStats& s : stats) AddSearchCounts(s, &frame_.stats);
  } else {
    for (int i : todo) {
      disparities.push_back(ahead_disparity_[i]);
      AddSearchCounts(ahead_stats_[i], &frame_.stats);
    }
  }
  const Camera& rect = rectifier_->rectified_camera();
  for (size_t j = 0; j < todo.size(); ++j) {
    if (!std::isfinite(disparities[j])) continue;
    const double left_x = frame_.left_rect[todo[j]].x();
    SetDisparity(*rectifier_, options_, todo[j],
                 disparities[j] - correction_.BiasPx(left_x - disparities[j], rect.fx(), rect.cx()),
                 &frame_);
  }
  search_ms_ += timer.ElapsedMs();
}

StereoFrame StereoFrameSearch::Complete() && {
  std::vector<int> rest;
  for (size_t i = 0; i < searched_.size(); ++i) {
    if (!searched_[i]) rest.push_back(static_cast<int>(i));
  }
  Search(rest);
  pair_.reset();
  return std::move(frame_);
}

StereoFrame BuildStereoFrame(const cv::Mat& left_raw, const cv::Mat& right_raw,
                             const FeatureExtractor& extractor, const StereoRectifier& rectifier,
                             const StereoMatchOptions& options,
                             const DisparityCorrection& correction) {
  return StereoFrameSearch(left_raw, right_raw, extractor, rectifier, options, correction)
      .Complete();
}

}  // namespace visloc::mapping
