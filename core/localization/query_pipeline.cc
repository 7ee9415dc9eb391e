#include "core/localization/query_pipeline.h"

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
  tracker_ = std::make_unique<PoseTracker>(std::move(map), camera_, options_.tracker);
  relocalizer_ = std::make_unique<Relocalizer>(*tracker_, options_.relocalization);
}

QueryFrame QueryPipeline::Extract(const cv::Mat& image, ExtractStats* stats,
                                  double* undistort_ms) const {
  CheckImage(image, camera_);
  FeatureSet features = extractor_->Extract(image, stats);
  const Timer undistort;
  QueryFrame frame(std::move(features), camera_);
  if (undistort_ms) *undistort_ms = undistort.ElapsedMs();
  return frame;
}

QueryFrame QueryPipeline::ExtractForRelocalization(const cv::Mat& image) const {
  CheckImage(image, camera_);
  return QueryFrame(relocalization_extractor_->Extract(image), camera_);
}

RelocalizationResult QueryPipeline::RelocalizeImage(const cv::Mat& image) const {
  const Timer timer;
  const QueryFrame frame = ExtractForRelocalization(image);
  const double features_ms = timer.ElapsedMs();
  RelocalizationResult found = relocalizer_->Relocalize(frame);
  found.times.features_ms = features_ms;
  found.ms = timer.ElapsedMs();
  return found;
}

}  // namespace visloc
