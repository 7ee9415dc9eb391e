#pragma once
// Image features: keypoints with descriptors, produced by an extractor chosen by the map's
// FeatureSettings, so mapping and localization always use the same detector and descriptor.
//
// Kinds:
//   "harris_surf16"  the paper's choice: Harris corners over a small scale space (same image
//                    resolution, increasing Gaussian scale), upright 16-D SURF-like float
//                    descriptors (harris_surf16.h). Compared by L2 distance.
//   "orb"            OpenCV ORB (oriented FAST + rotated BRIEF), 32-byte binary descriptors,
//                    compared by Hamming distance.
// Both spread features evenly over the image (per-cell quotas), as the paper's "intelligent
// management" of features does.

#include <algorithm>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "core/features/descriptor.h"
#include "core/features/feature_types.h"

namespace visloc {

struct ExtractStats {
  double detect_ms = 0.0;
  double describe_ms = 0.0;
  int detected = 0;  // Before the per-cell selection.
};

class FeatureExtractor {
 public:
  virtual ~FeatureExtractor() = default;
  // `grey` is 8-bit single channel. Throws CheckError otherwise.
  virtual FeatureSet Extract(const cv::Mat& grey, ExtractStats* stats = nullptr) const = 0;
  virtual const FeatureSettings& settings() const = 0;
};

// The default settings of a kind ("harris_surf16" or "orb"); throws InputError otherwise.
FeatureSettings DefaultFeatureSettings(const std::string& kind);
// Creates the extractor for settings read from a map (unknown parameters are an InputError).
std::unique_ptr<FeatureExtractor> CreateFeatureExtractor(const FeatureSettings& settings);

// The same settings with `max_features` corners per image.
FeatureSettings WithMaxFeatures(const FeatureSettings& settings, int max_features);
// The corner count for a `width` x `height` image, given the count for 320x240 (the paper's
// resolution): scaled with the image's side length (the square root of its area), up to
// `max_count`. A 752x480 image of a real scene holds structure at twice the density the paper's
// 600 corners cover at 320x240, and a fixed count would leave most of it unused.
int FeatureCountForImage(int count_at_320x240, int width, int height, int max_count = 1500);
// `settings` whose max_features is the count at 320x240, with the count for the image size.
FeatureSettings FeatureSettingsForImage(const FeatureSettings& settings, int width, int height);

// The settings for query images of a localization session: the map's detector and descriptor
// (so descriptors stay comparable), with at most `max_features` corners (0 keeps the map's) and,
// when `finest_scale_only`, detection at the finest scale only. The seed paper does the same
// for speed (paper 000, sec. 6.3): corners of the coarser scales are still in the map, but a
// single scale finds enough of them for the pose, at a fraction of the detection time.
FeatureSettings QueryFeatureSettings(const FeatureSettings& map_settings, int max_features,
                                     bool finest_scale_only);

// Indices into `pixels` (listed best first) of at most `max_items`: the best of each cell of a
// grid over the image up to an equal quota, then the best of the rest, in that order.
std::vector<int> SpreadOverGrid(const std::vector<Eigen::Vector2f>& pixels,
                                const cv::Size& image_size, int grid_cols, int grid_rows,
                                int max_items);

// SpreadOverGrid with the items offered one at a time, best first, for a caller that finds them
// in that order and would rather not list them first.
class GridSpread {
 public:
  GridSpread(const cv::Size& image_size, int grid_cols, int grid_rows, int max_items);
  // The cell (row-major) of a pixel; pixels outside the image count in the nearest cell.
  // Inline: detection asks for thousands of corners a frame.
  int Cell(const Eigen::Vector2f& pixel) const {
    const int cx = std::clamp(static_cast<int>(pixel.x() * grid_cols_ / image_size_.width), 0,
                              grid_cols_ - 1);
    const int cy = std::clamp(static_cast<int>(pixel.y() * grid_rows_ / image_size_.height), 0,
                              grid_rows_ - 1);
    return cy * grid_cols_ + cx;
  }
  // Offers item `index`, in `cell`, worse than every item offered before.
  void Offer(int index, int cell);
  // SpreadOverGrid's answer for the items offered.
  std::vector<int> Chosen() const;

 private:
  cv::Size image_size_;
  int grid_cols_, grid_rows_, max_items_, quota_;
  std::vector<int> used_;  // Items chosen per cell.
  std::vector<int> chosen_, rest_;
};

// Makes OpenCV run every call on the calling thread. visloc parallelizes across sessions (one
// engine worker per core); OpenCV's own thread pool on top of that oversubscribes the cores, and
// on 320x240 images its hand-off costs more than the work it spreads (measured: 10% of a
// detection in TBB and the scheduler). Programs call it once at start; timings then mean one
// core per frame, for the ORB reference too.
void RunOpenCvOnCallingThread();

}  // namespace visloc
