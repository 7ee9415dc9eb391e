#pragma once
// Multi-scale Harris corners with upright 16-D SURF-like descriptors (seed paper 000, sec. 3.2).
//
// Detection: for each scale sigma_i of a small scale space (sigma_i >= 2 px on the half-size
// image), the Harris response R = det(M) - k tr(M)^2 of the structure tensor M (gradients of
// the image smoothed at 0.7 sigma_i, in 8/16-bit integers; Gaussian window sigma_i truncated at
// +-2 sigma), non-maximum suppression in 3x3, a quadratic fit for the sub-pixel position, and a
// threshold relative to the strongest response in the corner's grid cell and in the image.
// Corners found at several scales are merged
// (strongest kept, none within 2 px of a stronger one). An even spread is enforced by per-cell
// quotas on a grid (SpreadOverGrid).
//
// Description (Bay et al., "SURF", CVIU 2008, reduced to 2x2 sub-regions): a square of side
// 12 sigma around the corner, not rotated (upright), split into 2x2 sub-regions; in each,
// Haar wavelet responses dx, dy of size 2 sigma at a 6x6 sample grid, Gaussian weighted, give
// (sum dx, sum dy, sum |dx|, sum |dy|). The 16 values are normalized to unit length, which
// makes the descriptor invariant to contrast changes. Haar responses come from an integral
// image in constant time per sample; the smallest wavelet (2x2 pixels, the finest scale a query
// uses) from a per-image response table, with the same values.

#include <vector>

#include <opencv2/core.hpp>

#include "core/features/features.h"

namespace visloc {

struct HarrisSurf16Options {
  std::vector<double> scales_px = {1.2, 2.0, 3.2};  // Gaussian sigmas of the scale space.
  double harris_k = 0.04;
  // A corner's response must reach `cell_relative_threshold` of the strongest in its quota cell
  // (grid_cols x grid_rows) and `relative_threshold` of the strongest in the image. The
  // response grows with the fourth power of contrast, so these are tiny: 1e-4 is a tenth of
  // the cell's strongest contrast, 1e-5 a eighteenth of the image's. Contrast varies across a
  // real image (a checkerboard beside a dull floor): relative to the image alone, the strong
  // parts leave the weak ones without corners. The image-wide floor keeps noise in flat cells
  // out. Maps made before cell thresholds record none (0 turns it off) and 0.005.
  double relative_threshold = 1e-5;
  double cell_relative_threshold = 1e-4;
  int max_features = 600;
  int grid_cols = 8;  // Quota cells across the image.
  int grid_rows = 6;
  int border_px = 8;  // No corners this close to the border (the descriptor needs room).
  void Check() const;
};

class HarrisSurf16Extractor final : public FeatureExtractor {
 public:
  explicit HarrisSurf16Extractor(const HarrisSurf16Options& options);
  FeatureSet Extract(const cv::Mat& grey, ExtractStats* stats = nullptr) const override;
  const FeatureSettings& settings() const override { return settings_; }

  std::vector<Keypoint> Detect(const cv::Mat& grey, int* detected = nullptr) const;
  // Descriptors for the keypoints (CV_32F, 16 columns). Keypoints too close to the border for
  // their scale are described from a clamped region.
  cv::Mat Describe(const cv::Mat& grey, const std::vector<Keypoint>& keypoints) const;

 private:
  // Detect's last step: `candidates` (unordered) merged, thresholded by cell and selected.
  std::vector<Keypoint> MergeAndSelect(const std::vector<Keypoint>& candidates,
                                       const cv::Size& size, int* detected) const;

  HarrisSurf16Options options_;
  FeatureSettings settings_;
};

// Harris response (CV_32F, the image's size) at Gaussian scale `sigma_px` of an 8-bit image:
// det(M) - k tr(M)^2 of the structure tensor M of 3x3 Sobel gradients of the image smoothed at
// 0.7 sigma, weighted by a Gaussian window of sigma (both truncated at +-2 sigma, at least 5
// taps), with OpenCV's reflect-101 border at every stage. Scale-normalized by sigma^4, in units of
// gradients of the image scaled to [0, 1]. `strongest` receives the largest value, or 0 when
// none is positive. sigma_px up to 10.
cv::Mat HarrisResponse(const cv::Mat& grey, double sigma_px, double k, float* strongest);

// cv::GaussianBlur(grey, smoothed, (2 half + 1) squared, sigma_px) of an 8-bit image, the same
// bytes (OpenCV's fixed-point kernel and arithmetic), several times faster.
void GaussianBlurLikeOpenCv(const cv::Mat& grey, double sigma_px, int half, cv::Mat* smoothed);

// The keypoints strongest first (equal responses in their given order), without those whose
// rounded pixel lies in the radius-2 disc (dx^2 + dy^2 <= 5 px^2) of a stronger one kept: one
// corner where several scales, or two close maxima, found it. Every pixel must round to one of
// an image of `size` (CheckError otherwise).
std::vector<Keypoint> MergeAcrossScales(std::vector<Keypoint> keypoints, const cv::Size& size);

// Indices of at most `max_features` keypoints: the strongest of each grid cell up to an equal
// quota, then the strongest of the rest.
std::vector<int> SelectEvenlyIndices(const std::vector<Keypoint>& keypoints,
                                     const cv::Size& image_size, int grid_cols, int grid_rows,
                                     int max_features);

}  // namespace visloc
