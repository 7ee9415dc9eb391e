#pragma once
// One stereo frame prepared for mapping: features of the raw left image, their rectified
// positions, their matches along the rectified right image's rows and the triangulated points.
//
// Descriptors are computed on the raw left image (as localization will see it); geometry uses
// rectified coordinates, in which the right camera is the left one shifted by the baseline
// along +x (seed paper 000, eqs. 1-3):
//   Z = f B / d,  X = (u - cx) Z / f,  Y = (v - cy) Z / f,  d = u_left - u_right.
//
// Each left keypoint is searched for along its row of the rectified right image by zero-mean
// normalized cross-correlation (ZNCC) of a small patch, not among keypoints detected
// independently in the right image: a corner the right detector ranks differently, or that a
// per-cell quota leaves out, still has its match, and ZNCC does not depend on the two cameras'
// exposure. The best disparity must correlate strongly and clearly better than any other
// (repetitive texture is refused), and is then refined to a few hundredths of a pixel.

#include <memory>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "core/camera/disparity_correction.h"
#include "core/camera/stereo_rectifier.h"
#include "core/features/descriptor_matching.h"
#include "core/features/features.h"

namespace visloc::mapping {

struct StereoMatchOptions {
  double min_depth_m = 0.3;  // Nearer points are out of range: the largest disparity searched.
  // The smallest disparity accepted. A limit in pixels, not metres: how far a rig triangulates
  // grows with its focal length and baseline (KITTI: 386 m at 1 px, the generated humanoid head
  // 23 m), while depth precision is set by the disparity's error (~0.05 px after refinement: 5%
  // of the depth at 1 px).
  double min_disparity_px = 1.0;
  int patch_radius_px = 3;  // ZNCC window: (2r + 1)^2 pixels.
  double min_zncc = 0.8;    // The best disparity's correlation.
  // Uniqueness: (1 - best) <= uniqueness * (1 - second best), the second best more than a pixel
  // from the best.
  double uniqueness = 0.5;
  // Disparity refinement: the left patch is aligned along the right image's row by Gauss-Newton
  // on the zero-mean SSD, with the disparity allowed to vary linearly across the patch (slanted
  // surfaces); this measures disparity to a few hundredths of a pixel where the correlation
  // peak is good to a tenth.
  int refine_patch_radius_px = 7;
  double refine_max_shift_px = 1.0;  // Larger corrections mean a wrong match: rejected.
  // Threads a frame uses (core/util/parallel.h; 0: every core): the left image's features beside
  // the rectification, then the keypoints' searches split among them. Same frame for any count.
  // A MapBuilder sets it from MapBuilderOptions::threads.
  int threads = 1;
  void Check() const;
};

// What happened to a frame's left keypoints, for diagnostics (dataset check, build failures).
struct StereoMatchStats {
  int keypoints = 0;        // Left keypoints.
  int searched = 0;         // With a full patch on the rectified canvas and a disparity range.
  int weak = 0;             // Best correlation below min_zncc.
  int ambiguous = 0;        // Failed the uniqueness test.
  int refine_rejected = 0;  // Refinement failed or moved the disparity too far.
  int out_of_range = 0;     // The refined disparity left [min_disparity_px, max disparity].
  int matched = 0;
};

struct StereoFrame {
  FeatureSet left;                             // Raw left image features.
  std::vector<Eigen::Vector2d> left_rect;      // Rectified positions of left keypoints.
  KeypointGrid grid;                           // left_rect, for radius searches.
  std::vector<double> right_x_rect;            // Matched right rectified x, or NaN.
  std::vector<Eigen::Vector3d> point_in_rect;  // Triangulated point (rectified left frame), or NaN.
  StereoMatchStats stats;
  int stereo_matches() const { return stats.matched; }
  bool HasDepth(size_t i) const { return point_in_rect[i].allFinite(); }
};

// Refines disparity `d` of rectified left pixel (x, y) by aligning a (2r+1)^2 patch of `left`
// with `right` along the row (both CV_32F rectified images; `left_gradient_x` is the left
// image's central-difference x gradient). Returns false when the patch leaves the image or the
// alignment does not converge.
bool RefineDisparity(const cv::Mat& left, const cv::Mat& left_gradient_x, const cv::Mat& right,
                     double x, double y, int radius, double* d);

// Takes a further `change` of the disparity correction off a frame's stereo matches (their
// right columns and points; a match whose disparity leaves the accepted range is dropped), as
// BuildStereoFrame would have with the sum of the two.
void CorrectStereoFrame(const DisparityCorrection& change, const StereoRectifier& rectifier,
                        const StereoMatchOptions& options, StereoFrame* frame);

struct RectifiedPair;  // stereo_frame.cc: the rectified images the row searches read.

// A stereo frame whose keypoints' row searches are made when asked for. Tracking needs the
// stereo matches of the keypoints it matched to landmarks, a keyframe all of them; most frames
// are not keyframes, and the searches with their refinement are most of a frame's cost. A
// keypoint's match is the same whenever it is searched, alone or with others: the frame
// complete is BuildStereoFrame's, value for value.
class StereoFrameSearch {
 public:
  // The left image's features beside the rectification; nothing searched yet. `rectifier` must
  // outlive the search.
  StereoFrameSearch(const cv::Mat& left_raw, const cv::Mat& right_raw,
                    const FeatureExtractor& extractor, const StereoRectifier& rectifier,
                    const StereoMatchOptions& options, const DisparityCorrection& correction = {});
  // A frame searched already, every keypoint.
  explicit StereoFrameSearch(StereoFrame complete);
  ~StereoFrameSearch();
  StereoFrameSearch(StereoFrameSearch&&) noexcept;
  StereoFrameSearch& operator=(StereoFrameSearch&&) noexcept;

  // The frame so far: a keypoint not searched yet has no match (NaN) and is not in its stats.
  const StereoFrame& frame() const { return frame_; }
  // Searches those of keypoints `features` (indices into frame().left) not searched yet.
  void Search(const std::vector<int>& features);
  // Runs every keypoint's search now, before any Search, and releases the rectified images:
  // Search then only takes the disparity correction off the results kept. On the thread that
  // prepares frames ahead of a map build, the searches leave the mapping thread (the same
  // results: a search does not depend on the correction, which is taken off after).
  void SearchAhead();
  // Every keypoint searched; the rectified images released.
  StereoFrame Complete() &&;
  // Wall time spent in Search so far (ms): a map build counts it with the features.
  double search_ms() const { return search_ms_; }
  // The keypoints searched so far.
  int searched() const { return searched_count_; }
  // The rig's disparity correction the searches take off, before any is made: a frame
  // prepared beside another's mapping gets the correction as it stands when its turn comes.
  void SetCorrection(const DisparityCorrection& correction);
  // Wall time the features and the rectification took (ms).
  double prepare_ms() const { return prepare_ms_; }

 private:
  StereoFrame frame_;
  const StereoRectifier* rectifier_ = nullptr;
  StereoMatchOptions options_;
  DisparityCorrection correction_;
  std::unique_ptr<RectifiedPair>
      pair_;  // Null once every keypoint is searched (or searched ahead).
  std::vector<bool> searched_;
  // From SearchAhead, per keypoint: the disparity found (rectified px, uncorrected; NaN: none)
  // and its search's counts.
  std::vector<double> ahead_disparity_;
  std::vector<StereoMatchStats> ahead_stats_;
  double search_ms_ = 0.0, prepare_ms_ = 0.0;
  int searched_count_ = 0;
};

// `correction` is the rig's disparity bias (core/camera/disparity_correction.h), taken off every
// measured disparity: right_x_rect and point_in_rect hold corrected values.
StereoFrame BuildStereoFrame(const cv::Mat& left_raw, const cv::Mat& right_raw,
                             const FeatureExtractor& extractor, const StereoRectifier& rectifier,
                             const StereoMatchOptions& options,
                             const DisparityCorrection& correction = {});

}  // namespace visloc::mapping
