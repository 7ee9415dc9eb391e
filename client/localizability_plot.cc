#include "client/localizability_plot.h"

#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>

#include "core/image/image_codec.h"
#include "core/util/check.h"
#include "core/util/strings.h"

namespace visloc::cli {
namespace {

constexpr int kMarginPx = 50;
constexpr int kLegendPx = 70;

// Red (no inliers) -> yellow (the good threshold) -> green (three times it), BGR.
cv::Scalar InlierColor(double inliers, double good_inliers) {
  const double t = std::clamp(inliers / (3.0 * good_inliers), 0.0, 1.0);
  const double yellow_at = 1.0 / 3.0;
  if (t < yellow_at) return cv::Scalar(40, 40 + 180 * t / yellow_at, 220);
  const double u = (t - yellow_at) / (1.0 - yellow_at);
  return cv::Scalar(40, 220 - 60 * u, 220 * (1.0 - u));
}

// A grid line every 1, 2, 5, 10, ... metres, whichever leaves 4 to 10 lines across `extent_m`.
double GridStep(double extent_m) {
  for (double step : {0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0, 500.0}) {
    if (extent_m / step <= 10.0) return step;
  }
  return 1000.0;
}

struct Frame {
  double min_x, min_y, px_per_m;
  int height;
  cv::Point Px(double x, double y) const {
    return {kMarginPx + static_cast<int>(std::lround((x - min_x) * px_per_m)),
            height - kMarginPx - kLegendPx - static_cast<int>(std::lround((y - min_y) * px_per_m))};
  }
};

void DrawWheels(const LocalizabilityGrid& grid, const Frame& f, double good_inliers,
                cv::Mat* image) {
  const double radius_px = 0.5 * grid.cell_m * f.px_per_m;
  const double half_wedge = 180.0 / grid.headings;
  for (int iy = 0; iy < grid.cells_y; ++iy) {
    for (int ix = 0; ix < grid.cells_x; ++ix) {
      const Eigen::Vector2d c = grid.CellCenter(ix, iy);
      for (int h = 0; h < grid.headings; ++h) {
        const double inliers = grid.at(ix, iy, h).expected_inliers;
        if (inliers <= 0.0) continue;
        // Image angles run clockwise (y down): the site's heading negated.
        const double mid = -grid.heading_deg(h);
        cv::ellipse(*image, f.Px(c.x(), c.y()),
                    cv::Size(static_cast<int>(radius_px), static_cast<int>(radius_px)), 0,
                    mid - half_wedge, mid + half_wedge, InlierColor(inliers, good_inliers),
                    cv::FILLED, cv::LINE_AA);
      }
    }
  }
}

void DrawMetricGrid(const LocalizabilityGrid& grid, const Frame& f, cv::Mat* image) {
  const double max_x = grid.min_x_m + grid.cells_x * grid.cell_m;
  const double max_y = grid.min_y_m + grid.cells_y * grid.cell_m;
  const double step = GridStep(std::max(max_x - grid.min_x_m, max_y - grid.min_y_m));
  const cv::Scalar line(215, 215, 215), text(90, 90, 90);
  for (double x = std::ceil(grid.min_x_m / step) * step; x <= max_x; x += step) {
    cv::line(*image, f.Px(x, grid.min_y_m), f.Px(x, max_y), line, 1);
    cv::putText(*image, StrCat(FormatFixed(x, 1), " m"), f.Px(x, grid.min_y_m) + cv::Point(-14, 16),
                cv::FONT_HERSHEY_SIMPLEX, 0.38, text, 1, cv::LINE_AA);
  }
  for (double y = std::ceil(grid.min_y_m / step) * step; y <= max_y; y += step) {
    cv::line(*image, f.Px(grid.min_x_m, y), f.Px(max_x, y), line, 1);
    cv::putText(*image, StrCat(FormatFixed(y, 1), " m"), f.Px(grid.min_x_m, y) + cv::Point(-48, 4),
                cv::FONT_HERSHEY_SIMPLEX, 0.38, text, 1, cv::LINE_AA);
  }
  // The site's axes at its origin, one grid step long, when the origin is in view.
  if (grid.min_x_m <= 0 && 0 <= max_x && grid.min_y_m <= 0 && 0 <= max_y) {
    cv::arrowedLine(*image, f.Px(0, 0), f.Px(step, 0), cv::Scalar(40, 40, 200), 2, cv::LINE_AA, 0,
                    0.15);
    cv::arrowedLine(*image, f.Px(0, 0), f.Px(0, step), cv::Scalar(40, 160, 40), 2, cv::LINE_AA, 0,
                    0.15);
    cv::putText(*image, "x", f.Px(step, 0) + cv::Point(4, 4), cv::FONT_HERSHEY_SIMPLEX, 0.45,
                cv::Scalar(40, 40, 200), 1, cv::LINE_AA);
    cv::putText(*image, "y", f.Px(0, step) + cv::Point(4, -4), cv::FONT_HERSHEY_SIMPLEX, 0.45,
                cv::Scalar(40, 160, 40), 1, cv::LINE_AA);
  }
}

void DrawMap(const LocalizabilityGrid& grid, const LocalizationMap& map, const Frame& f,
             cv::Mat* image) {
  const auto& points = map.map().points;
  const size_t stride = std::max<size_t>(1, points.size() / 20000);
  for (size_t j = 0; j < points.size(); j += stride) {
    const Eigen::Vector3d p = grid.site_from_map * points[j].position_in_map;
    cv::circle(*image, f.Px(p.x(), p.y()), 0, cv::Scalar(110, 110, 110), cv::FILLED);
  }
  const auto& keyframes = map.map().keyframes;
  for (size_t k = 1; k < keyframes.size(); ++k) {
    const Eigen::Vector3d a = grid.site_from_map * keyframes[k - 1].map_from_cam.translation;
    const Eigen::Vector3d b = grid.site_from_map * keyframes[k].map_from_cam.translation;
    cv::line(*image, f.Px(a.x(), a.y()), f.Px(b.x(), b.y()), cv::Scalar(200, 90, 30), 1,
             cv::LINE_AA);
  }
}

void DrawLegend(double good_inliers, const std::string& title, cv::Mat* image) {
  const int top = image->rows - kLegendPx + 10;
  const int width = 300;
  for (int i = 0; i < width; ++i) {
    const double inliers = 3.0 * good_inliers * i / (width - 1);
    cv::line(*image, {kMarginPx + i, top}, {kMarginPx + i, top + 14},
             InlierColor(inliers, good_inliers));
  }
  const cv::Scalar text(40, 40, 40);
  for (int tick = 0; tick <= 3; ++tick) {
    const int x = kMarginPx + (width - 1) * tick / 3;
    cv::line(*image, {x, top + 14}, {x, top + 19}, text);
    cv::putText(*image, StrCat(static_cast<int>(good_inliers * tick), tick == 3 ? "+" : ""),
                {x - 6, top + 32}, cv::FONT_HERSHEY_SIMPLEX, 0.4, text, 1, cv::LINE_AA);
  }
  cv::putText(*image, "expected inliers (each wedge: a heading; good from the yellow on)",
              {kMarginPx + width + 12, top + 12}, cv::FONT_HERSHEY_SIMPLEX, 0.4, text, 1,
              cv::LINE_AA);
  cv::putText(*image, title, {kMarginPx, 30}, cv::FONT_HERSHEY_SIMPLEX, 0.5, text, 1, cv::LINE_AA);
}

}  // namespace

void WriteLocalizabilityPng(const LocalizabilityPlotInput& input, const std::string& path) {
  VISLOC_CHECK(input.grid != nullptr, "nothing to draw");
  const LocalizabilityGrid& grid = *input.grid;
  const double extent_m = std::max(grid.cells_x, grid.cells_y) * grid.cell_m;
  // At least 14 px a cell so its wheel reads, at most 1,400 px across.
  const double px_per_m = std::clamp(1000.0 / extent_m, 14.0 / grid.cell_m, 1400.0 / extent_m);
  const int width = static_cast<int>(grid.cells_x * grid.cell_m * px_per_m) + 2 * kMarginPx;
  const int height =
      static_cast<int>(grid.cells_y * grid.cell_m * px_per_m) + 2 * kMarginPx + kLegendPx;
  cv::Mat image(std::max(height, 200), std::max(width, 720), CV_8UC3, cv::Scalar(255, 255, 255));
  const Frame frame{grid.min_x_m, grid.min_y_m, px_per_m, image.rows};
  DrawMetricGrid(grid, frame, &image);
  DrawWheels(grid, frame, input.good_inliers, &image);
  if (input.map) DrawMap(grid, *input.map, frame, &image);
  DrawLegend(input.good_inliers, input.title, &image);
  std::string why;
  if (!image::WritePng(path, image, 6, &why)) throw InputError(why);
}

}  // namespace visloc::cli
