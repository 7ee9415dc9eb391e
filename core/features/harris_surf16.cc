// Harris-SURF16: options and the extractor, detection (harris_response.cc, harris_corners.cc)
// then description (surf16_descriptor.cc).
#include "core/features/harris_surf16.h"

#include "core/util/check.h"
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
