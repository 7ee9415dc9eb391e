#pragma once
// The query side of localization for one camera, built once and shared by every consumer: a
// session's Localizer, the single-image Relocalize RPC, `visloc bench` and the localization
// benchmark. It owns the map's detector at the query settings (the finest scale, the query's
// keypoint budget), and the tracker and relocalizer with the pixel radii scaled from their
// 320-pixel values to the camera's width. One place, so the consumers cannot drift apart.

#include <memory>
#include <optional>

#include <opencv2/core.hpp>

#include "core/features/features.h"
#include "core/localization/localizer_options.h"
#include "core/localization/pose_tracker.h"
#include "core/localization/query_frame.h"
#include "core/localization/relocalizer.h"

namespace visloc {

class QueryPipeline {
 public:
  // `options` as given (radii at 320 px); the pipeline keeps them scaled to `camera`.
  QueryPipeline(std::shared_ptr<const LocalizationMap> map, const Camera& camera,
                const LocalizerOptions& options);

  // Detects and describes the image's keypoints and undistorts them through the camera (that
  // step's time in `undistort_ms`). The image is resampled to the map camera's focal length
  // when the two differ (LocalizerOptions::resample_ratio); the keypoints are in the camera's
  // pixels either way. Throws InputError for an image that is not 8-bit grey of the camera's
  // size.
  QueryFrame Extract(const cv::Mat& image, ExtractStats* stats = nullptr,
                     double* undistort_ms = nullptr) const;
  // The same with the relocalization features: all of the map's scales, more corners
  // (LocalizerOptions::max_relocalization_features). Throws as Extract does.
  QueryFrame ExtractForRelocalization(const cv::Mat& image) const;
  // Global relocalization of one image, with nothing known about where it was taken; `ms`
  // includes the feature extraction. `tracking_frame`, when given, receives the tracking
  // features (Extract) when the first pass extracted them, so a caller verifying the pose need
  // not extract them again.
  RelocalizationResult RelocalizeImage(const cv::Mat& image,
                                       std::optional<QueryFrame>* tracking_frame = nullptr) const;

  const Camera& camera() const { return camera_; }
  const LocalizerOptions& options() const { return options_; }  // Scaled.
  const PoseTracker& tracker() const { return *tracker_; }
  const Relocalizer& relocalizer() const { return *relocalizer_; }

 private:
  Camera camera_;
  LocalizerOptions options_;
  std::unique_ptr<FeatureExtractor> extractor_;
  std::unique_ptr<FeatureExtractor> relocalization_extractor_;
  std::unique_ptr<PoseTracker> tracker_;
  std::unique_ptr<Relocalizer> relocalizer_;
  // Query pixels per map pixel at the same angle (the focal lengths' ratio) when query images
  // are resampled to the map's, else 1.
  double resample_ = 1.0;

  // `extractor` on the image, at the map camera's scale (resample_), keypoints in the camera's
  // pixels; the resampling's time counts as detection.
  FeatureSet ExtractAtMapScale(const FeatureExtractor& extractor, const cv::Mat& image,
                               ExtractStats* stats) const;
};

}  // namespace visloc
