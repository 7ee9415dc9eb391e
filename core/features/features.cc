#include "core/features/features.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

#include <opencv2/features2d.hpp>

#include "core/features/harris_surf16.h"
#include "core/util/check.h"
#include "core/util/timer.h"

namespace visloc {

GridSpread::GridSpread(const cv::Size& image_size, int grid_cols, int grid_rows, int max_items)
    : image_size_(image_size),
      grid_cols_(grid_cols),
      grid_rows_(grid_rows),
      max_items_(max_items),
      quota_(std::max(1, max_items / (grid_cols * grid_rows))),
      used_(grid_cols * grid_rows, 0) {}

void GridSpread::Offer(int index, int cell) {
  int& count = used_[cell];
  // With fewer items wanted than cells, the quota of 1 would otherwise take one per cell.
  if (count < quota_ && static_cast<int>(chosen_.size()) < max_items_) {
    ++count;
    chosen_.push_back(index);
  } else if (static_cast<int>(rest_.size()) < max_items_) {  // More could never be taken.
    rest_.push_back(index);
  }
}

std::vector<int> GridSpread::Chosen() const {
  std::vector<int> chosen = chosen_;
  for (size_t i = 0; i < rest_.size() && static_cast<int>(chosen.size()) < max_items_; ++i) {
    chosen.push_back(rest_[i]);
  }
  return chosen;
}

std::vector<int> SpreadOverGrid(const std::vector<Eigen::Vector2f>& pixels,
                                const cv::Size& image_size, int grid_cols, int grid_rows,
                                int max_items) {
  GridSpread spread(image_size, grid_cols, grid_rows, max_items);
  for (int i = 0; i < static_cast<int>(pixels.size()); ++i) spread.Offer(i, spread.Cell(pixels[i]));
  return spread.Chosen();
}

// 1 rather than 0: both run every call on the caller, but 0 makes Debian's OpenCV set up its TBB
// backend in a way that crashes LeakSanitizer's exit-time scan (the ASan build of `visloc bench`
// exited 1 with "Tracer caught signal 11").
void RunOpenCvOnCallingThread() { cv::setNumThreads(1); }

namespace {

struct OrbOptions {
  int max_features = 600;
  double scale_factor = 1.2;
  int levels = 4;
  int fast_threshold = 12;
  int grid_cols = 8;
  int grid_rows = 6;
};

class OrbExtractor final : public FeatureExtractor {
 public:
  explicit OrbExtractor(const OrbOptions& options) : options_(options) {
    VISLOC_CHECK(options.max_features > 0 && options.levels >= 1 && options.scale_factor > 1.0,
                 "ORB options");
    // Detect twice the quota, then keep an even spread of the strongest.
    orb_ = cv::ORB::create(2 * options.max_features, static_cast<float>(options.scale_factor),
                           options.levels, 19, 0, 2, cv::ORB::HARRIS_SCORE, 31,
                           options.fast_threshold);
    settings_.kind = "orb";
    settings_.descriptor_type = DescriptorType::kBinary;
    settings_.descriptor_dim = 32;
    settings_.params = {{"max_features", options.max_features},
                        {"scale_factor", options.scale_factor},
                        {"levels", options.levels},
                        {"fast_threshold", options.fast_threshold},
                        {"grid_cols", options.grid_cols},
                        {"grid_rows", options.grid_rows}};
  }

  FeatureSet Extract(const cv::Mat& grey, ExtractStats* stats) const override {
    VISLOC_CHECK(grey.type() == CV_8UC1 && !grey.empty(), "features need an 8-bit grey image");
    Timer timer;
    std::vector<cv::KeyPoint> detected;
    orb_->detect(grey, detected);
    std::vector<Keypoint> keypoints;
    for (const cv::KeyPoint& k : detected) {
      keypoints.push_back({Eigen::Vector2f(k.pt.x, k.pt.y), k.size / 2, k.response});
    }
    // compute() needs ORB's own keypoints (pyramid level, angle): select by index.
    std::vector<cv::KeyPoint> selected;
    for (int i : SelectEvenlyIndices(keypoints, grey.size(), options_.grid_cols, options_.grid_rows,
                                     options_.max_features)) {
      selected.push_back(detected[i]);
    }
    const double detect_ms = timer.ElapsedMs();
    timer.Restart();
    FeatureSet features;
    orb_->compute(grey, selected, features.descriptors);  // may drop border keypoints
    for (const cv::KeyPoint& k : selected) {
      features.keypoints.push_back({Eigen::Vector2f(k.pt.x, k.pt.y), k.size / 2, k.response});
    }
    if (stats) {
      stats->detect_ms = detect_ms;
      stats->describe_ms = timer.ElapsedMs();
      stats->detected = static_cast<int>(detected.size());
    }
    return features;
  }
  const FeatureSettings& settings() const override { return settings_; }

 private:
  OrbOptions options_;
  cv::Ptr<cv::ORB> orb_;
  FeatureSettings settings_;
};

// Reads parameters by name; any parameter the kind does not know is an error, so a map built
// with settings this visloc cannot honour is refused rather than silently misread.
class ParamReader {
 public:
  explicit ParamReader(const FeatureSettings& settings) : kind_(settings.kind) {
    for (const auto& [name, value] : settings.params) values_[name] = value;
  }
  template <typename T>
  void Read(const std::string& name, T* target) {
    const auto it = values_.find(name);
    if (it == values_.end()) return;
    *target = static_cast<T>(it->second);
    values_.erase(it);
  }
  void RequireAllRead() const {
    if (!values_.empty()) {
      throw InputError(
          StrCat("unknown ", kind_, " feature parameter '", values_.begin()->first, "'"));
    }
  }
  bool Has(const std::string& name) const { return values_.count(name) > 0; }

 private:
  std::string kind_;
  std::map<std::string, double> values_;
};

}  // namespace

FeatureSettings DefaultFeatureSettings(const std::string& kind) {
  FeatureSettings settings;
  settings.kind = kind;
  return CreateFeatureExtractor(settings)->settings();
}

std::unique_ptr<FeatureExtractor> CreateFeatureExtractor(const FeatureSettings& settings) {
  ParamReader params(settings);
  if (settings.kind == "harris_surf16") {
    HarrisSurf16Options options;
    if (params.Has("scale_0")) {
      options.scales_px.clear();
      for (int i = 0; params.Has("scale_" + std::to_string(i)); ++i) {
        double scale = 0;
        params.Read("scale_" + std::to_string(i), &scale);
        options.scales_px.push_back(scale);
      }
    }
    params.Read("harris_k", &options.harris_k);
    // Settings recorded before cell thresholds existed detect as they did: image-wide only.
    if (!settings.params.empty() && !params.Has("cell_relative_threshold")) {
      options.cell_relative_threshold = 0.0;
    }
    params.Read("relative_threshold", &options.relative_threshold);
    params.Read("cell_relative_threshold", &options.cell_relative_threshold);
    params.Read("max_features", &options.max_features);
    params.Read("grid_cols", &options.grid_cols);
    params.Read("grid_rows", &options.grid_rows);
    params.Read("border_px", &options.border_px);
    params.RequireAllRead();
    return std::make_unique<HarrisSurf16Extractor>(options);
  }
  if (settings.kind == "orb") {
    OrbOptions options;
    params.Read("max_features", &options.max_features);
    params.Read("scale_factor", &options.scale_factor);
    params.Read("levels", &options.levels);
    params.Read("fast_threshold", &options.fast_threshold);
    params.Read("grid_cols", &options.grid_cols);
    params.Read("grid_rows", &options.grid_rows);
    params.RequireAllRead();
    return std::make_unique<OrbExtractor>(options);
  }
  throw InputError(
      StrCat("unknown feature kind '", settings.kind, "' (expected harris_surf16 or orb)"));
}

FeatureSettings WithMaxFeatures(const FeatureSettings& settings, int max_features) {
  VISLOC_CHECK(max_features > 0, "max_features ", max_features);
  FeatureSettings scaled = settings;
  bool found = false;
  for (auto& [name, value] : scaled.params) {
    if (name == "max_features") {
      value = max_features;
      found = true;
    }
  }
  VISLOC_CHECK(found, settings.kind, " settings have no max_features");
  return scaled;
}

int FeatureCountForImage(int count_at_320x240, int width, int height, int max_count) {
  VISLOC_CHECK(count_at_320x240 > 0 && width > 0 && height > 0, "feature count ",
               count_at_320x240, " for ", width, "x", height);
  const double scale = std::sqrt(static_cast<double>(width) * height / (320.0 * 240.0));
  return std::clamp(static_cast<int>(std::lround(count_at_320x240 * scale)),
                    std::min(count_at_320x240, max_count), max_count);
}

FeatureSettings FeatureSettingsForImage(const FeatureSettings& settings, int width, int height) {
  int count = 0;
  for (const auto& [name, value] : settings.params) {
    if (name == "max_features") count = static_cast<int>(value);
  }
  return WithMaxFeatures(settings, FeatureCountForImage(count, width, height));
}

FeatureSettings QueryFeatureSettings(const FeatureSettings& map_settings, int max_features,
                                     bool finest_scale_only) {
  VISLOC_CHECK(max_features >= 0, "max_features ", max_features);
  FeatureSettings query = map_settings;
  query.params.clear();
  double finest_scale = std::numeric_limits<double>::max();
  for (const auto& [name, value] : map_settings.params) {
    if (name.rfind("scale_", 0) == 0 && name != "scale_factor") {
      finest_scale = std::min(finest_scale, value);
    }
  }
  for (auto [name, value] : map_settings.params) {
    if (name == "max_features" && max_features > 0) value = max_features;
    if (finest_scale_only) {
      // Harris scales: keep the smallest as the only one. ORB: the full-resolution level.
      if (name.rfind("scale_", 0) == 0 && name != "scale_factor") {
        if (name != "scale_0") continue;
        value = finest_scale;
      }
      if (name == "levels" && map_settings.kind == "orb") value = 1;
    }
    query.params.emplace_back(name, value);
  }
  return query;
}

}  // namespace visloc
