#include "sim/texture.h"

#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>

#include "core/util/check.h"
#include "core/util/random.h"

namespace visloc::sim {

Texture::Texture(const cv::Mat& albedo, double texel_size_m) : texel_size_m_(texel_size_m) {
  VISLOC_CHECK(albedo.type() == CV_8UC1 && !albedo.empty(), "texture must be 8-bit grey");
  VISLOC_CHECK(texel_size_m > 0, "texel size ", texel_size_m);
  levels_.push_back(albedo.clone());
  while (levels_.back().cols > 1 || levels_.back().rows > 1) {
    cv::Mat next;
    const cv::Mat& last = levels_.back();
    cv::resize(last, next, cv::Size(std::max(1, last.cols / 2), std::max(1, last.rows / 2)), 0, 0,
               cv::INTER_AREA);
    levels_.push_back(next);
  }
  for (const cv::Mat& level : levels_) {
    texel_u_m_.push_back(texel_size_m * levels_[0].cols / level.cols);
    texel_v_m_.push_back(texel_size_m * levels_[0].rows / level.rows);
  }
}

float Texture::Bilinear(int level, double u_texels, double v_texels) const {
  const cv::Mat& image = levels_[level];
  // Texel centres sit at integer + 0.5.
  const double x = std::clamp(u_texels - 0.5, 0.0, image.cols - 1.0);
  const double y = std::clamp(v_texels - 0.5, 0.0, image.rows - 1.0);
  const int x0 = std::min(static_cast<int>(x), image.cols - 1);
  const int y0 = std::min(static_cast<int>(y), image.rows - 1);
  const int x1 = std::min(x0 + 1, image.cols - 1);
  const int y1 = std::min(y0 + 1, image.rows - 1);
  const float fx = static_cast<float>(x - x0);
  const float fy = static_cast<float>(y - y0);
  const uint8_t* row0 = image.ptr<uint8_t>(y0);
  const uint8_t* row1 = image.ptr<uint8_t>(y1);
  const float top = row0[x0] + fx * (row0[x1] - row0[x0]);
  const float bottom = row1[x0] + fx * (row1[x1] - row1[x0]);
  return (top + fy * (bottom - top)) * (1.0f / 255.0f);
}

float Texture::Sample(double u_m, double v_m, double footprint_m) const {
  const double level = std::log2(std::max(footprint_m / texel_size_m_, 1.0));
  const int max_level = static_cast<int>(levels_.size()) - 1;
  const int l0 = std::min(static_cast<int>(level), max_level);
  const int l1 = std::min(l0 + 1, max_level);
  const float blend = static_cast<float>(std::min(level - l0, 1.0));
  const float a = Bilinear(l0, u_m / texel_u_m_[l0], v_m / texel_v_m_[l0]);
  if (blend <= 0.0f || l1 == l0) return a;
  const float b = Bilinear(l1, u_m / texel_u_m_[l1], v_m / texel_v_m_[l1]);
  return a + blend * (b - a);
}

namespace {

// Drawing helpers work in texel units with 4 bits of sub-texel precision and anti-aliasing.
constexpr int kShift = 4;
constexpr double kSubPixel = 1 << kShift;

cv::Point ToFixed(double x, double y) {
  return cv::Point(static_cast<int>(std::lround(x * kSubPixel)),
                   static_cast<int>(std::lround(y * kSubPixel)));
}

cv::Scalar Grey(double albedo) { return cv::Scalar(std::clamp(albedo, 0.0, 1.0) * 255.0); }

// A smooth random field of amplitude `amplitude` around `mean` with features ~`cell_m` apart.
cv::Mat SmoothField(int cols, int rows, double texel_m, double cell_m, double mean,
                    double amplitude, Rng& rng) {
  const int small_cols = std::max(2, static_cast<int>(cols * texel_m / cell_m) + 2);
  const int small_rows = std::max(2, static_cast<int>(rows * texel_m / cell_m) + 2);
  cv::Mat small(small_rows, small_cols, CV_32FC1);
  for (int r = 0; r < small_rows; ++r) {
    for (int c = 0; c < small_cols; ++c) {
      small.at<float>(r, c) = static_cast<float>(mean + amplitude * rng.Uniform(-1.0, 1.0));
    }
  }
  cv::Mat field;
  cv::resize(small, field, cv::Size(cols, rows), 0, 0, cv::INTER_CUBIC);
  cv::Mat out;
  field.convertTo(out, CV_8UC1, 255.0);
  return out;
}

void DrawRotatedRect(cv::Mat& image, double cx, double cy, double w, double h, double angle,
                     double albedo) {
  const double c = std::cos(angle), s = std::sin(angle);
  std::vector<cv::Point> corners;
  for (const auto& [du, dv] : {std::pair{-0.5, -0.5}, {0.5, -0.5}, {0.5, 0.5}, {-0.5, 0.5}}) {
    corners.push_back(ToFixed(cx + c * du * w - s * dv * h, cy + s * du * w + c * dv * h));
  }
  cv::fillConvexPoly(image, corners, Grey(albedo), cv::LINE_AA, kShift);
}

void DrawEllipse(cv::Mat& image, double cx, double cy, double rx, double ry, double angle,
                 double albedo) {
  cv::ellipse(image, ToFixed(cx, cy),
              cv::Size(static_cast<int>(rx * kSubPixel), static_cast<int>(ry * kSubPixel)),
              angle * 180.0 / M_PI, 0, 360, Grey(albedo), cv::FILLED, cv::LINE_AA, kShift);
}

void DrawTriangle(cv::Mat& image, double cx, double cy, double size, Rng& rng, double albedo) {
  std::vector<cv::Point> points;
  const double base = rng.Uniform(0, 2 * M_PI);
  for (int k = 0; k < 3; ++k) {
    const double a = base + k * 2.0 * M_PI / 3.0 + rng.Uniform(-0.4, 0.4);
    const double r = size * rng.Uniform(0.35, 0.6);
    points.push_back(ToFixed(cx + r * std::cos(a), cy + r * std::sin(a)));
  }
  cv::fillConvexPoly(image, points, Grey(albedo), cv::LINE_AA, kShift);
}

void DrawChecker(cv::Mat& image, double cx, double cy, double size, Rng& rng) {
  const int cells = rng.UniformInt(2, 4);
  const double cell = size / cells;
  const double dark = rng.Uniform(0.03, 0.25), light = rng.Uniform(0.7, 0.97);
  const double angle = rng.Uniform01() < 0.6 ? 0.0 : rng.Uniform(-0.5, 0.5);
  const double c = std::cos(angle), s = std::sin(angle);
  for (int i = 0; i < cells; ++i) {
    for (int j = 0; j < cells; ++j) {
      const double du = (i - (cells - 1) / 2.0) * cell, dv = (j - (cells - 1) / 2.0) * cell;
      DrawRotatedRect(image, cx + c * du - s * dv, cy + s * du + c * dv, cell, cell, angle,
                      (i + j) % 2 ? dark : light);
    }
  }
}

void DrawTextLines(cv::Mat& image, double cx, double cy, double size, Rng& rng, double albedo) {
  const int lines = rng.UniformInt(2, 5);
  const double line_height = size / (2.0 * lines);
  for (int l = 0; l < lines; ++l) {
    double x = cx - size / 2;
    const double y = cy - size / 2 + (2 * l + 0.5) * line_height;
    const double end = cx + size / 2 - rng.Uniform(0, size / 3);
    while (x < end) {
      const double word = line_height * rng.Uniform(1.0, 4.0);
      DrawRotatedRect(image, x + word / 2, y, word, line_height, 0.0, albedo);
      x += word + line_height * 0.8;
    }
  }
}

// Scatters `count` shapes with sizes log-uniform in [min_m, max_m], centred inside `region`
// (texels).
void ScatterShapes(cv::Mat& image, double texel_m, int count, double min_m, double max_m,
                   const cv::Rect2d& region, Rng& rng) {
  for (int i = 0; i < count; ++i) {
    const double size = std::exp(rng.Uniform(std::log(min_m), std::log(max_m))) / texel_m;
    const double cx = rng.Uniform(region.x, region.x + region.width);
    const double cy = rng.Uniform(region.y, region.y + region.height);
    const double albedo = rng.Uniform01() < 0.5 ? rng.Uniform(0.03, 0.35) : rng.Uniform(0.6, 0.97);
    const double angle = rng.Uniform(0, M_PI);
    switch (rng.UniformInt(0, 5)) {
      case 0:
        DrawRotatedRect(image, cx, cy, size, size * rng.Uniform(0.3, 1.0), angle, albedo);
        break;
      case 1:
        DrawEllipse(image, cx, cy, size / 2, size / 2 * rng.Uniform(0.5, 1.0), angle, albedo);
        break;
      case 2:
        DrawTriangle(image, cx, cy, size, rng, albedo);
        break;
      case 3:
        DrawChecker(image, cx, cy, size, rng);
        break;
      case 4:
        DrawTextLines(image, cx, cy, size, rng, albedo);
        break;
      default: {
        // A blob: a dark or bright disk with a ring, a strong scale-space extremum.
        DrawEllipse(image, cx, cy, size / 2, size / 2, 0, albedo);
        DrawEllipse(image, cx, cy, size / 4, size / 4, 0, 1.0 - albedo);
      }
    }
  }
}

void ScatterShapes(cv::Mat& image, double texel_m, int count, double min_m, double max_m,
                   Rng& rng) {
  ScatterShapes(image, texel_m, count, min_m, max_m, cv::Rect2d(0, 0, image.cols, image.rows), rng);
}

// Posters, notice boards and pictures: framed rectangles packed with content at many scales,
// with bare wall between them, as on a lab's walls.
void DrawPosters(cv::Mat& image, double texel_m, double area_m2, Rng& rng) {
  const int count = static_cast<int>(area_m2 * 0.9) + 1;
  for (int i = 0; i < count; ++i) {
    const double w = rng.Uniform(0.35, 1.1) / texel_m, h = rng.Uniform(0.3, 0.9) / texel_m;
    const double cx = rng.Uniform(0, image.cols);
    const double cy = rng.Uniform(0.15 * image.rows, 0.75 * image.rows);
    const double frame = rng.Uniform(0.01, 0.03) / texel_m;
    const double paper = rng.Uniform01() < 0.7 ? rng.Uniform(0.75, 0.95) : rng.Uniform(0.1, 0.3);
    DrawRotatedRect(image, cx, cy, w + 2 * frame, h + 2 * frame, 0, rng.Uniform(0.05, 0.3));
    DrawRotatedRect(image, cx, cy, w, h, 0, paper);
    const cv::Rect2d inside(cx - w / 2 + 0.1 * w, cy - h / 2 + 0.1 * h, 0.8 * w, 0.8 * h);
    const double poster_area_m2 = w * h * texel_m * texel_m;
    ScatterShapes(image, texel_m, static_cast<int>(poster_area_m2 * 60) + 2, 0.06, 0.3, inside,
                  rng);
    ScatterShapes(image, texel_m, static_cast<int>(poster_area_m2 * 120) + 2, 0.02, 0.07, inside,
                  rng);
  }
}

void DrawGrid(cv::Mat& image, double texel_m, double spacing_m, double line_m, double albedo) {
  const double spacing = spacing_m / texel_m, line = std::max(line_m / texel_m, 1.0);
  for (double x = spacing; x < image.cols; x += spacing) {
    DrawRotatedRect(image, x, image.rows / 2.0, line, image.rows, 0, albedo);
  }
  for (double y = spacing; y < image.rows; y += spacing) {
    DrawRotatedRect(image, image.cols / 2.0, y, image.cols, line, 0, albedo);
  }
}

}  // namespace

cv::Mat GenerateTexture(TextureStyle style, double width_m, double height_m, double texel_m,
                        uint64_t seed) {
  VISLOC_CHECK(width_m > 0 && height_m > 0 && texel_m > 0, "texture size ", width_m, "x", height_m,
               " at ", texel_m);
  const int cols = std::max(2, static_cast<int>(std::ceil(width_m / texel_m)));
  const int rows = std::max(2, static_cast<int>(std::ceil(height_m / texel_m)));
  Rng rng(seed * 0x9E3779B97F4A7C15ULL + static_cast<uint64_t>(style) + 1);
  const double area_m2 = width_m * height_m;
  switch (style) {
    case TextureStyle::kPosterWall: {
      cv::Mat image = SmoothField(cols, rows, texel_m, 0.6, 0.6, 0.06, rng);
      // Marks on the bare wall: switches, stickers, stains.
      ScatterShapes(image, texel_m, static_cast<int>(area_m2 * 6), 0.03, 0.2, rng);
      DrawPosters(image, texel_m, area_m2, rng);
      return image;
    }
    case TextureStyle::kFloor: {
      cv::Mat image = SmoothField(cols, rows, texel_m, 0.8, 0.45, 0.08, rng);
      ScatterShapes(image, texel_m, static_cast<int>(area_m2 * 40), 0.02, 0.06, rng);
      ScatterShapes(image, texel_m, static_cast<int>(area_m2 * 4), 0.08, 0.4, rng);
      DrawGrid(image, texel_m, 0.6, 0.008, 0.2);
      return image;
    }
    case TextureStyle::kCeiling: {
      cv::Mat image = SmoothField(cols, rows, texel_m, 1.0, 0.8, 0.03, rng);
      DrawGrid(image, texel_m, 0.6, 0.02, 0.45);
      for (double x = 0.9; x + 0.6 < width_m; x += 2.4) {
        for (double y = 0.9; y + 1.2 < height_m; y += 2.4) {
          DrawRotatedRect(image, (x + 0.3) / texel_m, (y + 0.6) / texel_m, 0.64 / texel_m,
                          1.24 / texel_m, 0, 0.25);
          DrawRotatedRect(image, (x + 0.3) / texel_m, (y + 0.6) / texel_m, 0.56 / texel_m,
                          1.16 / texel_m, 0, 0.98);
        }
      }
      return image;
    }
    case TextureStyle::kPlain:
      return SmoothField(cols, rows, texel_m, 1.5, 0.68, 0.025, rng);
    case TextureStyle::kBox: {
      cv::Mat image = SmoothField(cols, rows, texel_m, 0.3, 0.5, 0.06, rng);
      DrawRotatedRect(image, cols / 2.0, rows * rng.Uniform(0.2, 0.8), cols, 0.05 / texel_m, 0,
                      0.75);
      for (int label = 0; label < 2; ++label) {
        const double lx = rng.Uniform(0.25, 0.75) * cols, ly = rng.Uniform(0.25, 0.75) * rows;
        const double size = std::min(cols, rows) * rng.Uniform(0.25, 0.45);
        DrawRotatedRect(image, lx, ly, size * 1.3, size, 0, 0.93);
        DrawTextLines(image, lx, ly, size * 0.9, rng, 0.1);
      }
      ScatterShapes(image, texel_m, static_cast<int>(area_m2 * 30) + 3, 0.03, 0.15, rng);
      return image;
    }
    case TextureStyle::kPerson: {
      cv::Mat image(rows, cols, CV_8UC1, Grey(rng.Uniform(0.15, 0.4)));  // trousers
      const int waist = static_cast<int>(rows * 0.45);
      image(cv::Rect(0, 0, cols, waist)).setTo(Grey(rng.Uniform(0.5, 0.9)));  // shirt
      for (int stripe = 0; stripe < 4; ++stripe) {
        DrawRotatedRect(image, cols / 2.0, waist * (0.2 + 0.18 * stripe), cols, rows * 0.02, 0,
                        rng.Uniform(0.1, 0.3));
      }
      image(cv::Rect(0, 0, cols, std::max(1, rows / 9))).setTo(Grey(0.62));  // head
      return image;
    }
  }
  return cv::Mat();
}

void PaintPlain(cv::Mat* albedo, double texel_m, double u0_m, double u1_m, double v0_m, double v1_m,
                uint64_t seed) {
  const cv::Rect region =
      cv::Rect(static_cast<int>(u0_m / texel_m), static_cast<int>(v0_m / texel_m),
               static_cast<int>((u1_m - u0_m) / texel_m),
               static_cast<int>((v1_m - v0_m) / texel_m)) &
      cv::Rect(0, 0, albedo->cols, albedo->rows);
  if (region.empty()) return;
  const cv::Mat plain = GenerateTexture(TextureStyle::kPlain, region.width * texel_m,
                                        region.height * texel_m, texel_m, seed);
  plain(cv::Rect(0, 0, region.width, region.height)).copyTo((*albedo)(region));
}

}  // namespace visloc::sim
