#include "core/localization/query_pipeline.h"

#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>

#include "core/util/check.h"
#include "core/util/timer.h"

namespace visloc {
namespace {

// The radii are tuned at 320 pixels of width; a wider image of the same field of view needs
// proportionally wider ones.
LocalizerOptions ScaledToCamera(LocalizerOptions options, const Camera& camera) {
  options.Check();
  if (options.scale_radii_with_width) {
    const double scale = camera.width() / 320.0;
    options.tracker.search_radius_px *= scale;
    options.tracker.refine_radius_px *= scale;
    options.tracker.map_error_px *= scale;
  }
  return options;
}

// Throws InputError unless `image` is 8-bit grey of the camera's size.
void CheckImage(const cv::Mat& image, const Camera& camera) {
  if (image.empty() || image.type() != CV_8UC1) {
    throw InputError("the image must be 8-bit grey (got type " + std::to_string(image.type()) +
                     (image.empty() ? ", empty)" : ")"));
  }
  if (image.cols != camera.width() || image.rows != camera.height()) {
    throw InputError(StrCat("the image is ", image.cols, "x", image.rows, " but the camera is ",
                            camera.width(), "x", camera.height()));
  }
}

}  // namespace

QueryPipeline::QueryPipeline(std::shared_ptr<const LocalizationMap> map, const Camera& camera,
                             const LocalizerOptions& options)
    : camera_(camera), options_(ScaledToCamera(options, camera)) {
  VISLOC_CHECK(map != nullptr, "no map");
  extractor_ = CreateFeatureExtractor(QueryFeatureSettings(
      map->map().features, options_.max_query_features, options_.finest_scale_only));
  relocalization_extractor_ = CreateFeatureExtractor(QueryFeatureSettings(
      map->map().features, options_.max_relocalization_features, /*finest_scale_only=*/false));
  const double focal_ratio = camera_.fx() / map->map().camera.fx();
  if (std::max(focal_ratio, 1.0 / focal_ratio) > options_.resample_ratio) {
    resample_ = focal_ratio;
  }
  tracker_ = std::make_unique<PoseTracker>(std::move(map), camera_, options_.tracker);
  relocalizer_ = std::make_unique<Relocalizer>(*tracker_, options_.relocalization);
}

FeatureSet QueryPipeline::ExtractAtMapScale(const FeatureExtractor& extractor, const cv::Mat& image,
                                            ExtractStats* stats) const {
  CheckImage(image, camera_);
  if (resample_ == 1.0) return extractor.Extract(image, stats);
  const Timer timer;
  const cv::Size resampled_size(std::max(1, static_cast<int>(std::lround(image.cols / resample_))),
                                std::max(1, static_cast<int>(std::lround(image.rows / resample_))));
  cv::Mat resampled;
  cv::resize(image, resampled, resampled_size, 0, 0,
             resample_ > 1.0 ? cv::INTER_AREA : cv::INTER_LINEAR);
  const double resample_ms = timer.ElapsedMs();
  FeatureSet features = extractor.Extract(resampled, stats);
  if (stats) stats->detect_ms += resample_ms;
  // Back to the camera's pixels (pixel centres at integer coordinates in both images).
  const float sx = static_cast<float>(image.cols) / resampled_size.width;
  const float sy = static_cast<float>(image.rows) / resampled_size.height;
  for (Keypoint& k : features.keypoints) {
    k.pixel = Eigen::Vector2f((k.pixel.x() + 0.5f) * sx - 0.5f, (k.pixel.y() + 0.5f) * sy - 0.5f);
    k.scale_px *= sx;
  }
  return features;
}

QueryFrame QueryPipeline::Extract(const cv::Mat& image, ExtractStats* stats,
                                  double* undistort_ms) const {
  FeatureSet features = ExtractAtMapScale(*extractor_, image, stats);
  const Timer undistort;
  QueryFrame frame(std::move(features), camera_);
  if (undistort_ms) *undistort_ms = undistort.ElapsedMs();
  return frame;
}

QueryFrame QueryPipeline::ExtractForRelocalization(const cv::Mat& image) const {
  return QueryFrame(ExtractAtMapScale(*relocalization_extractor_, image, nullptr), camera_);
}

RelocalizationResult QueryPipeline::RelocalizeImage(
    const cv::Mat& image, std::optional<QueryFrame>* tracking_frame) const {
  const Timer timer;
  // One pass: the features `extract` gives, then the relocalizer on them (kept in `*kept` when
  // given).
  const auto pass = [&](auto extract, std::optional<QueryFrame>* kept) {
    const Timer features;
    std::optional<QueryFrame> frame(extract());
    const double features_ms = features.ElapsedMs();
    RelocalizationResult found = relocalizer_->Relocalize(*frame);
    found.times.features_ms = features_ms;
    if (kept) *kept = std::move(frame);
    return found;
  };
  if (tracking_frame) tracking_frame->reset();
  RelocalizationResult found;
  int passes = 0;
  if (options_.relocalize_with_tracking_features_first) {
    found = pass([&] { return Extract(image); }, tracking_frame);
    passes = 1;
  }
  if (!found.success) {
    const RelocalizationTimes first = found.times;
    found = pass([&] { return ExtractForRelocalization(image); }, nullptr);
    found.times += first;
    ++passes;
  }
  found.feature_passes = passes;
  found.ms = timer.ElapsedMs();
  return found;
}

}  // namespace visloc
