#include "core/features/features.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <limits>
#include <set>

#include <opencv2/imgproc.hpp>

#include "core/features/harris_surf16.h"
#include "core/util/check.h"
#include "sim/renderer.h"
#include "sim/sequences.h"

namespace visloc {
namespace {

// Two views of the simulated room 5 cm apart, with the first view's depth.
struct ViewPair {
  Camera camera;
  cv::Mat first, second, first_depth;
  Rigid3d world_from_first, world_from_second;
};

const ViewPair& Views() {
  static const ViewPair views = [] {
    ViewPair v;
    const sim::StereoRig rig = sim::MakeRig(sim::RigOptions{});
    v.camera = rig.left.camera;
    sim::RoomOptions room;
    room.texel_m = 0.006;
    const sim::World world = sim::MakeRoom(room);
    const sim::Renderer renderer(v.camera, 2);
    const Rigid3d body(RotationFromRollPitchYaw(0, 0.05, 0.3), Eigen::Vector3d(0.2, -0.4, 1.45));
    v.world_from_first = body * rig.left.body_from_cam;
    v.world_from_second = v.world_from_first * Rigid3d(RotationFromRollPitchYaw(0.0, 0.02, 0.0),
                                                       Eigen::Vector3d(0.05, 0.0, 0.03));
    sim::SensorModel sensor;
    Rng noise(3);
    v.first = sensor.Capture(
        renderer.RenderRadiance(world, v.world_from_first, 0.0, &v.first_depth), &noise);
    v.second = sensor.Capture(renderer.RenderRadiance(world, v.world_from_second, 0.0), &noise);
    return v;
  }();
  return views;
}

// Where a keypoint of the first view must appear in the second, from the rendered depth.
bool Transfer(const ViewPair& v, const Keypoint& k, Eigen::Vector2d* pixel) {
  const float depth = v.first_depth.at<float>(static_cast<int>(std::lround(k.pixel.y())),
                                              static_cast<int>(std::lround(k.pixel.x())));
  if (depth <= 0) return false;
  const Eigen::Vector3d in_first = depth * v.camera.Unproject(k.pixel.cast<double>());
  return v.camera.Project(v.world_from_second.Inverse() * (v.world_from_first * in_first), pixel);
}

struct MatchQuality {
  double repeatability = 0.0;    // Share of transferable corners detected again within 1.5 px.
  double median_error_px = 0.0;  // Of those re-detections.
  int matched = 0;               // Distinctive nearest-descriptor matches within a 30 px window.
  double precision = 0.0;        // Share of them on the right corner (within 2 px).
};

// Repeatability: the share of first-view corners detected again within 1.5 px of where the true
// geometry puts them, and the accuracy of those positions. Then matching precision:
// nearest-descriptor matches (with a ratio test) that land on the right corner.
MatchQuality Measure(const ViewPair& v, const FeatureSet& a, const FeatureSet& b) {
  int transferable = 0, repeated = 0, matched = 0, correct = 0;
  std::vector<double> errors;
  for (size_t i = 0; i < a.size(); ++i) {
    Eigen::Vector2d expected;
    if (!Transfer(v, a.keypoints[i], &expected) || !v.camera.IsInImage(expected, 10)) continue;
    ++transferable;
    double nearest = 1e9;
    for (const Keypoint& k : b.keypoints)
      nearest = std::min(nearest, (k.pixel.cast<double>() - expected).norm());
    if (nearest < 1.5) {
      ++repeated;
      errors.push_back(nearest);
    }
    NearestTwo candidates;
    for (int j = 0; j < static_cast<int>(b.size()); ++j) {
      if ((b.keypoints[j].pixel.cast<double>() - expected).norm() > 30) continue;  // search window
      candidates.Offer(DescriptorDistance(a.descriptors, static_cast<int>(i), b.descriptors, j), j);
    }
    const int best_j = candidates.best_index;
    if (candidates.Distinctive(0.8f, std::numeric_limits<float>::max())) {
      ++matched;
      if ((b.keypoints[best_j].pixel.cast<double>() - expected).norm() < 2.0) ++correct;
    }
  }
  std::sort(errors.begin(), errors.end());
  MatchQuality quality;
  quality.repeatability = static_cast<double>(repeated) / std::max(1, transferable);
  quality.median_error_px = errors.empty() ? 1e9 : errors[errors.size() / 2];
  quality.matched = matched;
  quality.precision = static_cast<double>(correct) / std::max(1, matched);
  return quality;
}

class FeatureKindTest : public ::testing::TestWithParam<std::string> {};

TEST_P(FeatureKindTest, EvenlySpreadRepeatableAndMatchable) {
  const ViewPair& v = Views();
  const auto extractor = CreateFeatureExtractor(DefaultFeatureSettings(GetParam()));
  ExtractStats stats;
  const FeatureSet a = extractor->Extract(v.first, &stats);
  const FeatureSet b = extractor->Extract(v.second);
  EXPECT_GE(a.size(), 300u);
  EXPECT_LE(a.size(), 600u);
  EXPECT_EQ(a.descriptors.rows, static_cast<int>(a.size()));
  EXPECT_EQ(a.descriptors.cols, extractor->settings().descriptor_dim);
  std::set<int> cells;
  for (const Keypoint& k : a.keypoints)
    cells.insert(static_cast<int>(k.pixel.y() / 40) * 8 + static_cast<int>(k.pixel.x() / 40));
  EXPECT_GE(cells.size(), 32u) << "features must cover most of the 8x6 grid";

  const MatchQuality quality = Measure(v, a, b);
  std::printf(
      "%s: %zu features (%d detected), repeatability %.2f, median error %.2f px, "
      "%d matches with precision %.2f; detect %.2f ms, describe %.2f ms\n",
      GetParam().c_str(), a.size(), stats.detected, quality.repeatability, quality.median_error_px,
      quality.matched, quality.precision, stats.detect_ms, stats.describe_ms);
  EXPECT_GT(quality.repeatability, 0.5);
  EXPECT_LT(quality.median_error_px, 0.5);
  EXPECT_GT(quality.matched, 100);
  // Harris keeps corners of weak contrast wherever a cell has nothing stronger (real images
  // need them: FindsCornersInLowContrastNextToHighContrast); in the rendered room they match a
  // little less precisely than the strong ones (0.89 against 0.90 with only the strongest).
  EXPECT_GT(quality.precision, 0.87);
}

INSTANTIATE_TEST_SUITE_P(Kinds, FeatureKindTest, ::testing::Values("harris_surf16", "orb"));

// A real image mixes strong and weak contrast: a checkerboard beside a dull floor. Corners of
// the weak half must be found too, not only the strongest of the image.
TEST(HarrisSurf16Test, FindsCornersInLowContrastNextToHighContrast) {
  cv::Mat image(240, 320, CV_8UC1);
  for (int y = 0; y < image.rows; ++y) {
    for (int x = 0; x < image.cols; ++x) {
      const bool dark = ((x / 12) + (y / 12)) % 2 == 0;
      // Left: black and white. Right: two greys 20 levels apart.
      image.at<uint8_t>(y, x) = x < 160 ? (dark ? 10 : 245) : (dark ? 118 : 138);
    }
  }
  const FeatureSet features =
      CreateFeatureExtractor(DefaultFeatureSettings("harris_surf16"))->Extract(image);
  int right = 0;
  for (const Keypoint& k : features.keypoints) right += k.pixel.x() > 170;
  std::printf("%zu corners, %d in the low-contrast half\n", features.size(), right);
  EXPECT_GT(right, 100);
  // Maps recorded before cell thresholds keep their image-wide threshold.
  FeatureSettings legacy = DefaultFeatureSettings("harris_surf16");
  legacy.params.erase(
      std::remove_if(legacy.params.begin(), legacy.params.end(),
                     [](const auto& p) { return p.first == "cell_relative_threshold"; }),
      legacy.params.end());
  for (auto& [name, value] : legacy.params) {
    if (name == "relative_threshold") value = 0.005;
  }
  int legacy_right = 0;
  for (const Keypoint& k : CreateFeatureExtractor(legacy)->Extract(image).keypoints) {
    legacy_right += k.pixel.x() > 170;
  }
  EXPECT_EQ(legacy_right, 0);
}

// A localization session detects at the finest scale only; its corners must still find the
// map's (all-scale) corners and descriptors.
TEST(QueryFeatureSettingsTest, FinestScaleQueryMatchesAllScaleMapFeatures) {
  const FeatureSettings map_settings = DefaultFeatureSettings("harris_surf16");
  const FeatureSettings query_settings = QueryFeatureSettings(map_settings, 600, true);
  const std::vector<std::pair<std::string, double>> expected_params = {
      {"scale_0", 1.2},
      {"harris_k", 0.04},
      {"relative_threshold", 1e-5},
      {"cell_relative_threshold", 1e-4},
      {"max_features", 600},
      {"grid_cols", 8},
      {"grid_rows", 6},
      {"border_px", 8}};
  EXPECT_EQ(query_settings.params, expected_params);
  EXPECT_EQ(QueryFeatureSettings(map_settings, 0, false).params, map_settings.params);
  for (const auto& [name, value] : QueryFeatureSettings(map_settings, 250, false).params) {
    if (name == "max_features") {
      EXPECT_EQ(value, 250.0);
    }
  }

  const ViewPair& v = Views();
  const FeatureSet all_scales = CreateFeatureExtractor(map_settings)->Extract(v.first);
  const FeatureSet query_features = CreateFeatureExtractor(query_settings)->Extract(v.second);
  EXPECT_EQ(query_features.size(), 600u);
  for (const Keypoint& k : query_features.keypoints) ASSERT_FLOAT_EQ(k.scale_px, 1.2f);
  // The map's corners of the finest scale are the ones a finest-scale query can match (the
  // coarser ones' descriptors cover larger windows; the pose's RANSAC rejects what they draw).
  FeatureSet map_features;
  for (size_t i = 0; i < all_scales.size(); ++i) {
    if (all_scales.keypoints[i].scale_px != 1.2f) continue;
    map_features.keypoints.push_back(all_scales.keypoints[i]);
    map_features.descriptors.push_back(all_scales.descriptors.row(static_cast<int>(i)));
  }
  EXPECT_GT(map_features.size(), all_scales.size() / 2);
  const MatchQuality quality = Measure(v, map_features, query_features);
  std::printf(
      "finest-scale query: %zu of %zu map corners at the finest scale, %d matches with "
      "precision %.2f\n",
      map_features.size(), all_scales.size(), quality.matched, quality.precision);
  EXPECT_GT(quality.matched, 100);
  EXPECT_GT(quality.precision, 0.9);

  FeatureSettings orb = DefaultFeatureSettings("orb");
  for (const auto& [name, value] : QueryFeatureSettings(orb, 0, true).params) {
    if (name == "levels") {
      EXPECT_EQ(value, 1.0);
    }
  }
}

TEST(HarrisSurf16Test, DescriptorIgnoresContrastAndBrightness) {
  const ViewPair& v = Views();
  const HarrisSurf16Extractor extractor(HarrisSurf16Options{});
  const std::vector<Keypoint> keypoints = extractor.Detect(v.first);
  cv::Mat dimmer;
  v.first.convertTo(dimmer, CV_8U, 0.5, 20);  // half the contrast, brighter black level
  const cv::Mat a = extractor.Describe(v.first, keypoints);
  const cv::Mat b = extractor.Describe(dimmer, keypoints);
  std::vector<float> distances;
  for (int i = 0; i < a.rows; ++i) distances.push_back(DescriptorDistance(a, i, b, i));
  std::sort(distances.begin(), distances.end());
  EXPECT_LT(distances[distances.size() / 2], 0.05f);  // unit vectors: 0 same, up to 2 opposite
  EXPECT_NEAR(cv::norm(a.row(0)), 1.0, 1e-5);
}

// The descriptor straight from its definition (harris_surf16.h), one pixel at a time; a
// wavelet that overhangs the image sums only its part inside. The reference for the fast paths
// (small wavelets read from a per-image response table, larger ones from an integral image).
std::vector<float> ReferenceDescriptor(const cv::Mat& grey, const Keypoint& k) {
  const double s = k.scale_px;
  const int half = std::max(2, static_cast<int>(std::lround(2 * s)) & ~1) / 2;
  const auto pixel = [&](int x, int y) {
    const bool inside = x >= 0 && y >= 0 && x < grey.cols && y < grey.rows;
    return inside ? static_cast<int>(grey.at<uint8_t>(y, x)) : 0;
  };
  const auto box = [&](int x0, int y0, int x1, int y1) {  // [x0, x1) x [y0, y1)
    int sum = 0;
    for (int y = y0; y < y1; ++y) {
      for (int x = x0; x < x1; ++x) sum += pixel(x, y);
    }
    return sum;
  };
  std::vector<double> sums(16, 0.0);
  for (int sy = 0; sy < 12; ++sy) {
    for (int sx = 0; sx < 12; ++sx) {
      const double ox = (sx - 5.5) * s, oy = (sy - 5.5) * s;
      const int x = static_cast<int>(std::floor(k.pixel.x() + ox + 0.5));
      const int y = static_cast<int>(std::floor(k.pixel.y() + oy + 0.5));
      const double dx = box(x, y - half, x + half, y + half) - box(x - half, y - half, x, y + half);
      const double dy = box(x - half, y, x + half, y + half) - box(x - half, y - half, x + half, y);
      const double w = std::exp(-(ox * ox + oy * oy) / (2 * (3.3 * s) * (3.3 * s)));
      double* cell = &sums[4 * ((sy / 6) * 2 + sx / 6)];
      cell[0] += w * dx;
      cell[1] += w * dy;
      cell[2] += w * std::abs(dx);
      cell[3] += w * std::abs(dy);
    }
  }
  double norm = 0;
  for (double v : sums) norm += v * v;
  std::vector<float> descriptor;
  for (double v : sums) descriptor.push_back(static_cast<float>(v / std::sqrt(norm)));
  return descriptor;
}

TEST(HarrisSurf16Test, DescriptorsEqualTheirDefinitionInsideAndAtTheBorder) {
  const cv::Mat& image = Views().first;
  const HarrisSurf16Extractor extractor(HarrisSurf16Options{});
  std::vector<Keypoint> keypoints;
  // Inside, across the border, and inside but within a few pixels of the left and right
  // edges (where the larger wavelets' rows are computed in whole vectors moved off the edge).
  for (float scale : {1.2f, 2.0f, 3.2f}) {  // Wavelet half sizes 1, 2 and 3.
    for (const Eigen::Vector2f& pixel :
         {Eigen::Vector2f(100.3f, 80.6f), Eigen::Vector2f(200.5f, 150.5f),
          Eigen::Vector2f(2.2f, 3.7f), Eigen::Vector2f(318.6f, 120.0f),
          Eigen::Vector2f(297.0f, 100.0f), Eigen::Vector2f(306.0f, 60.0f),
          Eigen::Vector2f(21.0f, 90.0f), Eigen::Vector2f(14.0f, 200.0f)}) {
      keypoints.push_back({pixel, scale, 1.0f});
    }
  }
  const cv::Mat descriptors = extractor.Describe(image, keypoints);
  for (size_t i = 0; i < keypoints.size(); ++i) {
    const std::vector<float> expected = ReferenceDescriptor(image, keypoints[i]);
    for (int j = 0; j < 16; ++j) {
      EXPECT_NEAR(descriptors.at<float>(static_cast<int>(i), j), expected[j], 1e-5)
          << "keypoint " << keypoints[i].pixel.transpose() << " scale " << keypoints[i].scale_px;
    }
  }
}

// The Harris response by its definition, one OpenCV filter per step: 8-bit smoothing, Sobel
// gradients, the tensor's products, their Gaussian window, det - k trace^2 (reflect-101 borders
// throughout, OpenCV's default).
cv::Mat ReferenceHarris(const cv::Mat& grey, double sigma, double k) {
  const auto kernel = [](double s) {
    const int half = std::max(2, static_cast<int>(std::lround(2.0 * s)));
    return cv::Size(2 * half + 1, 2 * half + 1);
  };
  cv::Mat smoothed, ix, iy;
  cv::GaussianBlur(grey, smoothed, kernel(0.7 * sigma), 0.7 * sigma);
  cv::Sobel(smoothed, ix, CV_32F, 1, 0, 3);
  cv::Sobel(smoothed, iy, CV_32F, 0, 1, 3);
  cv::Mat ixx = ix.mul(ix), iyy = iy.mul(iy), ixy = ix.mul(iy);
  for (cv::Mat* m : {&ixx, &iyy, &ixy}) cv::GaussianBlur(*m, *m, kernel(sigma), sigma);
  const cv::Mat trace = ixx + iyy;
  const double norm = std::pow(sigma, 4) / std::pow(8.0 * 255.0, 4);
  return norm * (ixx.mul(iyy) - ixy.mul(ixy) - k * trace.mul(trace));
}

// The detector's own 8-bit blur must give cv::GaussianBlur's bytes: for the derivative scales
// of every default detector scale at both pyramid levels (0.7 sigma: 0.84, 1.4, 2.24 and 0.7,
// 1.12 at half size) and wider ones, on noise of odd sizes (borders reflected on all sides) and
// an image smaller than the window.
TEST(HarrisSurf16Test, BlurEqualsOpenCvByteForByte) {
  cv::RNG rng(7);
  for (const cv::Size size : {cv::Size(97, 61), cv::Size(64, 48), cv::Size(7, 40)}) {
    cv::Mat noise(size, CV_8UC1);
    rng.fill(noise, cv::RNG::UNIFORM, 0, 256);
    for (double sigma : {0.7, 0.84, 1.12, 1.4, 2.24, 3.5, 7.0}) {
      const int half = std::max(2, static_cast<int>(std::lround(2.0 * sigma)));
      cv::Mat ours, theirs;
      GaussianBlurLikeOpenCv(noise, sigma, half, &ours);
      cv::GaussianBlur(noise, theirs, cv::Size(2 * half + 1, 2 * half + 1), sigma);
      EXPECT_EQ(cv::countNonZero(ours != theirs), 0) << "sigma " << sigma << " " << size;
    }
  }
}

TEST(HarrisSurf16Test, ResponseEqualsItsDefinitionInsideAndAtTheBorder) {
  // Odd sizes and windows of 5, 7 and 11 taps (the last not unrolled), on the rendered room and on
  // a strip three rows high, where the window reflects more than once.
  const cv::Mat room = Views().first(cv::Rect(3, 5, 61, 47)).clone();
  const cv::Mat strip = Views().first(cv::Rect(40, 40, 33, 3)).clone();
  for (const cv::Mat* image : {&room, &strip}) {
    for (double sigma : {1.2, 1.6, 2.6}) {
      const cv::Mat expected = ReferenceHarris(*image, sigma, 0.04);
      float strongest = 0.0f;
      const cv::Mat response = HarrisResponse(*image, sigma, 0.04, &strongest);
      double expected_max = 0.0;
      cv::minMaxLoc(expected, nullptr, &expected_max);
      const double magnitude = cv::norm(expected, cv::NORM_INF);
      ASSERT_GT(magnitude, 0.0);
      // The strongest is never below 0: negative responses are never corners.
      EXPECT_NEAR(strongest, std::max(expected_max, 0.0), 1e-5 * magnitude) << "sigma " << sigma;
      EXPECT_LE(cv::norm(response, expected, cv::NORM_INF), 1e-5 * magnitude)
          << "sigma " << sigma << ", " << image->cols << "x" << image->rows;
    }
  }
  float strongest = 0.0f;
  EXPECT_THROW(HarrisResponse(cv::Mat(8, 8, CV_8UC3), 1.2, 0.04, &strongest), std::exception);
  EXPECT_THROW(HarrisResponse(room, 12.0, 0.04, &strongest), std::exception);  // 49 taps.
  EXPECT_THROW(HarrisResponse(room, 0.0, 0.04, &strongest), std::exception);
}

// MergeAcrossScales by its definition: strongest first (a stable order), each kept unless a
// kept one's rounded pixel is within dx^2 + dy^2 <= 5 of its own.
std::vector<Keypoint> ReferenceMerge(std::vector<Keypoint> found) {
  std::stable_sort(found.begin(), found.end(),
                   [](const Keypoint& a, const Keypoint& b) { return a.response > b.response; });
  std::vector<Keypoint> kept;
  for (const Keypoint& k : found) {
    const bool covered = std::any_of(kept.begin(), kept.end(), [&](const Keypoint& s) {
      const long dx = std::lround(k.pixel.x()) - std::lround(s.pixel.x());
      const long dy = std::lround(k.pixel.y()) - std::lround(s.pixel.y());
      return dx * dx + dy * dy <= 5;
    });
    if (!covered) kept.push_back(k);
  }
  return kept;
}

// One scale's corners by their definition, from HarrisSurf16Extractor's own response: every
// pixel at least `border` from the edge whose response reaches `relative` of the strongest and
// no 8-neighbour exceeds, at its quadratic sub-pixel peak; strongest first (ties in row-major
// order), none within a radius-2 disc of a stronger one. Written plainly, pixel by pixel.
std::vector<Keypoint> ReferenceCorners(const cv::Mat& grey, double sigma, double relative,
                                       int border) {
  float strongest = 0.0f;
  const cv::Mat r = HarrisResponse(grey, sigma, 0.04, &strongest);
  const float threshold = std::max(1e-12f, static_cast<float>(relative) * strongest);
  std::vector<Keypoint> found;
  for (int y = border; y < r.rows - border; ++y) {
    for (int x = border; x < r.cols - border; ++x) {
      const float v = r.at<float>(y, x);
      bool is_max = v >= threshold;
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) is_max = is_max && v >= r.at<float>(y + dy, x + dx);
      }
      if (!is_max) continue;
      const float left = r.at<float>(y, x - 1), right = r.at<float>(y, x + 1);
      const float up = r.at<float>(y - 1, x), down = r.at<float>(y + 1, x);
      const float dxx = right - 2 * v + left, dyy = down - 2 * v + up;
      Keypoint k;
      k.pixel = Eigen::Vector2f(
          x + (dxx < 0 ? std::clamp(-0.5f * (right - left) / dxx, -0.5f, 0.5f) : 0.0f),
          y + (dyy < 0 ? std::clamp(-0.5f * (down - up) / dyy, -0.5f, 0.5f) : 0.0f));
      k.scale_px = static_cast<float>(sigma);
      k.response = v;
      found.push_back(k);
    }
  }
  return ReferenceMerge(found);
}

TEST(HarrisSurf16Test, SingleScaleCornersAreTheResponsesMergedLocalMaxima) {
  // The detector packs flags 64 columns to a word: widths whose scanned span (width - 16) is
  // and is not a multiple of 64, so the last partial word is exercised; and both relative
  // thresholds. Blurred noise: corners everywhere, of every strength, a few in a word;
  // dots: more (past FlaggedColumns's unconditional part).
  cv::Mat noise(67, 203, CV_8UC1);
  cv::RNG(7).fill(noise, cv::RNG::UNIFORM, 0, 256);
  cv::Mat blurred;
  cv::GaussianBlur(noise, blurred, cv::Size(7, 7), 1.5);
  cv::Mat dots = blurred / 8;  // Dots every 4 px on faint noise: 16 corners in some words.
  for (int y = 2; y < dots.rows; y += 4) {
    for (int x = 2; x < dots.cols; x += 4) dots.at<uint8_t>(y, x) = 255;
  }
  for (const auto& [source, width] :
       {std::pair(blurred, 61), std::pair(blurred, 80), std::pair(blurred, 203),
        std::pair(dots, 144), std::pair(dots, 203)}) {
    const cv::Mat image = source.colRange(0, width).clone();
    for (double relative : {1e-5, 0.02}) {
      HarrisSurf16Options options;
      options.scales_px = {1.2};
      options.relative_threshold = relative;
      options.cell_relative_threshold = 0;
      options.max_features = 100000;
      const std::vector<Keypoint> detected = HarrisSurf16Extractor(options).Detect(image);
      const std::vector<Keypoint> expected =
          ReferenceCorners(image, 1.2, relative, options.border_px);
      ASSERT_GT(expected.size(), 10u) << width;
      ASSERT_EQ(detected.size(), expected.size()) << "width " << width << ", " << relative;
      for (size_t i = 0; i < expected.size(); ++i) {
        EXPECT_EQ(detected[i].response, expected[i].response) << i;
        EXPECT_EQ(detected[i].pixel, expected[i].pixel) << i;
      }
      // With a coarser scale, the finest one is scanned border to border for the maxima that
      // coarse corners move to; its own corners still keep out of the border.
      options.scales_px = {1.2, 2.0};
      const float last = static_cast<float>(width - options.border_px) - 0.5f;
      for (const Keypoint& k : HarrisSurf16Extractor(options).Detect(image)) {
        if (k.scale_px != 1.2f) continue;
        EXPECT_GE(k.pixel.x(), options.border_px - 0.5f);
        EXPECT_LE(k.pixel.x(), last) << "width " << width;
      }
    }
  }
}

TEST(HarrisSurf16Test, DetectionKeepsTheStrongOfEachCellThenSpreadsThemOverTheGrid) {
  // Detect merges, thresholds by cell and selects in one pass; by definition it is the three
  // steps in turn: the merged corners, those reaching `cell_relative` of the strongest merged
  // corner of their cell, then SelectEvenlyIndices's choice. Noise whose contrast falls from left
  // to right, so the cell threshold removes corners in some cells and not in others; as many
  // wanted as there are, and fewer.
  cv::Mat noise(96, 160, CV_8UC1);
  cv::RNG(3).fill(noise, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(noise, noise, cv::Size(5, 5), 1.0);
  for (int x = 0; x < noise.cols; ++x) noise.col(x) *= 1.0 - 0.9 * x / noise.cols;
  const cv::Size size = noise.size();
  HarrisSurf16Options options;
  options.scales_px = {1.2};
  options.grid_cols = 4;
  options.grid_rows = 3;
  options.cell_relative_threshold = 0.05;
  const std::vector<Keypoint> merged =
      ReferenceCorners(noise, 1.2, options.relative_threshold, options.border_px);
  const auto cell_of = [&](const Keypoint& k) {
    return std::clamp(static_cast<int>(k.pixel.x() * 4 / size.width), 0, 3) +
           4 * std::clamp(static_cast<int>(k.pixel.y() * 3 / size.height), 0, 2);
  };
  std::vector<float> strongest(12, 0.0f);
  for (const Keypoint& k : merged)
    strongest[cell_of(k)] = std::max(strongest[cell_of(k)], k.response);
  std::vector<Keypoint> strong;
  for (const Keypoint& k : merged) {
    if (k.response >= options.cell_relative_threshold * strongest[cell_of(k)]) strong.push_back(k);
  }
  ASSERT_LT(strong.size(), merged.size());
  ASSERT_GT(strong.size(), 60u);
  for (int wanted : {static_cast<int>(strong.size()), 60, 13}) {
    options.max_features = wanted;
    int detected = 0;
    const std::vector<Keypoint> selected = HarrisSurf16Extractor(options).Detect(noise, &detected);
    EXPECT_EQ(detected, static_cast<int>(strong.size()));
    const std::vector<int> expected = SelectEvenlyIndices(strong, size, 4, 3, wanted);
    ASSERT_EQ(selected.size(), expected.size()) << wanted;
    for (size_t i = 0; i < expected.size(); ++i) {
      EXPECT_EQ(selected[i].pixel, strong[expected[i]].pixel) << wanted << " " << i;
      EXPECT_EQ(selected[i].response, strong[expected[i]].response) << wanted << " " << i;
    }
  }
}

TEST(HarrisSurf16Test, MergeKeepsTheStrongestOfCloseCornersAnywhereInTheImage) {
  // Dense random corners, so that discs overlap everywhere: across the 64-pixel words of the
  // merge's bit mask, along every edge and in the corners of the image; some responses tie.
  const cv::Size size(203, 37);
  cv::RNG rng(11);
  std::vector<Keypoint> keypoints(1500);
  for (Keypoint& k : keypoints) {
    k.pixel = Eigen::Vector2f(rng.uniform(-0.49f, size.width - 0.51f),
                              rng.uniform(-0.49f, size.height - 0.51f));
    k.response = static_cast<float>(rng.uniform(1, 200));
  }
  const std::vector<Keypoint> merged = MergeAcrossScales(keypoints, size);
  const std::vector<Keypoint> expected = ReferenceMerge(keypoints);
  ASSERT_GT(expected.size(), 300u);
  ASSERT_EQ(merged.size(), expected.size());
  for (size_t i = 0; i < expected.size(); ++i) {
    EXPECT_EQ(merged[i].pixel, expected[i].pixel) << i;
    EXPECT_EQ(merged[i].response, expected[i].response) << i;
  }
  // A corner that rounds to no pixel of the image is refused, not written beyond the mask.
  for (const Eigen::Vector2f& outside :
       {Eigen::Vector2f(-0.5f, 3.0f), Eigen::Vector2f(5.0f, size.height - 0.5f),
        Eigen::Vector2f(size.width + 40.0f, 3.0f),
        Eigen::Vector2f(std::numeric_limits<float>::quiet_NaN(), 3.0f)}) {
    std::vector<Keypoint> with_outside = keypoints;
    with_outside[700].pixel = outside;
    EXPECT_THROW(MergeAcrossScales(with_outside, size), CheckError) << outside.transpose();
  }
}

TEST(SpreadOverGridTest, TakesTheBestPerCellAndNeverMoreThanAsked) {
  // 100 pixels, best first, on a 10x10 lattice over a 320x240 image with a 4x3 grid.
  std::vector<Eigen::Vector2f> pixels;
  for (int i = 0; i < 100; ++i) pixels.emplace_back(16.0f + 32 * (i % 10), 12.0f + 24 * (i / 10));
  for (int wanted : {3, 12, 50, 100, 200}) {
    const std::vector<int> chosen = SpreadOverGrid(pixels, cv::Size(320, 240), 4, 3, wanted);
    EXPECT_EQ(static_cast<int>(chosen.size()), std::min(wanted, 100)) << wanted;
    EXPECT_EQ(std::set<int>(chosen.begin(), chosen.end()).size(), chosen.size()) << wanted;
  }
  // Twelve wanted, twelve cells: one per cell, the first (best) pixel of each.
  const std::vector<int> one_per_cell = SpreadOverGrid(pixels, cv::Size(320, 240), 4, 3, 12);
  std::set<int> cells;
  for (int i : one_per_cell) {
    cells.insert(static_cast<int>(pixels[i].x() * 4 / 320) +
                 4 * static_cast<int>(pixels[i].y() * 3 / 240));
  }
  EXPECT_EQ(cells.size(), 12u);
  EXPECT_EQ(one_per_cell.front(), 0);
}

TEST(FeaturesTest, OpenCvRunsOnTheCallingThreadAfterwards) {
  RunOpenCvOnCallingThread();
  EXPECT_EQ(cv::getNumThreads(), 1);
}

TEST(FeatureSettingsTest, SettingsRoundTripAndUnknownsAreRefused) {
  const FeatureSettings settings = DefaultFeatureSettings("harris_surf16");
  EXPECT_EQ(settings.descriptor_dim, 16);
  EXPECT_EQ(CreateFeatureExtractor(settings)->settings().params, settings.params);
  FeatureSettings unknown = settings;
  unknown.params.emplace_back("sharpness", 3.0);
  EXPECT_THAT(
      [&] { CreateFeatureExtractor(unknown); },
      ::testing::ThrowsMessage<InputError>("unknown harris_surf16 feature parameter 'sharpness'"));
  FeatureSettings kind;
  kind.kind = "sift";
  EXPECT_THROW(CreateFeatureExtractor(kind), InputError);
  EXPECT_EQ(DefaultFeatureSettings("orb").descriptor_type, DescriptorType::kBinary);
}

}  // namespace
}  // namespace visloc
