#include "client/plot.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <sstream>

#include <opencv2/imgproc.hpp>

#include "core/image/image_codec.h"
#include "core/localization/localizer.h"  // FitKeyframePlane
#include "core/util/check.h"
#include "core/util/strings.h"

namespace visloc::cli {
namespace {

struct Rgb {
  int r, g, b;
};

Rgb RatioColor(double ratio) {
  const double t = std::clamp(ratio, 0.0, 1.0);
  // Red -> yellow -> green.
  return t < 0.5 ? Rgb{220, static_cast<int>(440 * t), 40}
                 : Rgb{static_cast<int>(220 * (1 - t) * 2), 180, 40};
}

// A 2D drawing surface in pixels, y down.
class Canvas {
 public:
  virtual ~Canvas() = default;
  virtual void Dot(double x, double y, double radius, Rgb color) = 0;
  virtual void Line(double x0, double y0, double x1, double y1, Rgb color, double width,
                    bool dashed) = 0;
  virtual void Text(double x, double y, const std::string& text, Rgb color) = 0;
  virtual void Save(const std::string& path) = 0;
};

class PngCanvas : public Canvas {
 public:
  PngCanvas(int width, int height) : image_(height, width, CV_8UC3, cv::Scalar(255, 255, 255)) {}
  void Dot(double x, double y, double radius, Rgb c) override {
    cv::circle(image_, cv::Point2d(x, y), std::max(1, static_cast<int>(std::lround(radius))),
               cv::Scalar(c.b, c.g, c.r), cv::FILLED, cv::LINE_AA);
  }
  void Line(double x0, double y0, double x1, double y1, Rgb c, double width, bool dashed) override {
    const int w = std::max(1, static_cast<int>(std::lround(width)));
    const double length = std::hypot(x1 - x0, y1 - y0);
    const int pieces = dashed ? std::max(1, static_cast<int>(length / 6)) : 1;
    for (int i = 0; i < pieces; i += dashed ? 2 : 1) {
      const double a = static_cast<double>(i) / pieces, b = static_cast<double>(i + 1) / pieces;
      cv::line(image_, cv::Point2d(x0 + a * (x1 - x0), y0 + a * (y1 - y0)),
               cv::Point2d(x0 + b * (x1 - x0), y0 + b * (y1 - y0)), cv::Scalar(c.b, c.g, c.r), w,
               cv::LINE_AA);
    }
  }
  void Text(double x, double y, const std::string& text, Rgb c) override {
    cv::putText(image_, text, cv::Point2d(x, y), cv::FONT_HERSHEY_SIMPLEX, 0.45,
                cv::Scalar(c.b, c.g, c.r), 1, cv::LINE_AA);
  }
  void Save(const std::string& path) override {
    std::string why;
    if (!image::WritePng(path, image_, 6, &why)) throw InputError(why);
  }

 private:
  cv::Mat image_;
};

class SvgCanvas : public Canvas {
 public:
  SvgCanvas(int width, int height) {
    out_ << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << width << "\" height=\""
         << height << "\" viewBox=\"0 0 " << width << " " << height << "\">\n"
         << "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
  }
  void Dot(double x, double y, double radius, Rgb c) override {
    out_ << "<circle cx=\"" << FormatFixed(x, 1) << "\" cy=\"" << FormatFixed(y, 1) << "\" r=\""
         << FormatFixed(radius, 1) << "\" fill=\"" << Color(c) << "\"/>\n";
  }
  void Line(double x0, double y0, double x1, double y1, Rgb c, double width, bool dashed) override {
    out_ << "<line x1=\"" << FormatFixed(x0, 1) << "\" y1=\"" << FormatFixed(y0, 1) << "\" x2=\""
         << FormatFixed(x1, 1) << "\" y2=\"" << FormatFixed(y1, 1) << "\" stroke=\"" << Color(c)
         << "\" stroke-width=\"" << FormatFixed(width, 1) << "\""
         << (dashed ? " stroke-dasharray=\"6,6\"" : "") << "/>\n";
  }
  void Text(double x, double y, const std::string& text, Rgb c) override {
    out_ << "<text x=\"" << FormatFixed(x, 1) << "\" y=\"" << FormatFixed(y, 1)
         << "\" font-family=\"sans-serif\" font-size=\"13\" fill=\"" << Color(c) << "\">" << text
         << "</text>\n";
  }
  void Save(const std::string& path) override {
    std::ofstream file(path);
    file << out_.str() << "</svg>\n";
    if (!file) throw InputError(path + ": cannot write SVG");
  }

 private:
  static std::string Color(Rgb c) { return StrCat("rgb(", c.r, ",", c.g, ",", c.b, ")"); }
  std::ostringstream out_;
};

std::unique_ptr<Canvas> MakeCanvas(const std::string& path, int width, int height) {
  if (EndsWith(path, ".svg")) return std::make_unique<SvgCanvas>(width, height);
  if (EndsWith(path, ".png")) return std::make_unique<PngCanvas>(width, height);
  throw InputError(path + ": the plot must be .png or .svg");
}

// Map frame -> 2D top-view coordinates (metres): two axes spanning the ground plane.
struct TopView {
  Eigen::Vector3d e1, e2;
  Eigen::Vector2d offset = Eigen::Vector2d::Zero();
  Eigen::Vector2d operator()(const Eigen::Vector3d& p) const {
    return Eigen::Vector2d(e1.dot(p), e2.dot(p)) + offset;
  }
};

TopView MakeTopView(const LocalizationMap& map) {
  // The site frame's x-y (z up) when the map knows up, as the operator's page draws it.
  if (const auto site_from_map = SiteFromMap(map.map().metadata)) {
    const Eigen::Matrix3d r = site_from_map->rotation.toRotationMatrix();
    return {r.row(0).transpose(), r.row(1).transpose(), site_from_map->translation.head<2>()};
  }
  const auto plane = FitKeyframePlane(map);
  const Eigen::Vector3d up = plane ? plane->first : Eigen::Vector3d(0, -1, 0);
  Eigen::Vector3d e1 = Eigen::Vector3d::UnitX() - up * up.x();
  if (e1.norm() < 1e-6) e1 = Eigen::Vector3d::UnitZ() - up * up.z();
  e1.normalize();
  // Seen from above (looking down -up), e2 completes a right-handed frame with e1 and up.
  return {e1, up.cross(e1)};
}

}  // namespace

PlotStats WriteTopViewPlot(const PlotInput& input, const std::string& path) {
  VISLOC_CHECK(input.map != nullptr, "no map to plot");
  if (!EndsWith(path, ".svg") && !EndsWith(path, ".png")) {
    throw InputError(path + ": the plot must be .png or .svg");
  }
  const LocalizationMap& map = *input.map;
  const TopView view = MakeTopView(map);
  // Extent: keyframes and trajectories, plus the points' central 98% (outliers stretch it).
  std::vector<Eigen::Vector2d> anchors;
  for (const auto& c : map.keyframe_centers()) anchors.push_back(view(c));
  for (const auto& s : input.estimate) anchors.push_back(view(s.pose.translation));
  for (const auto& s : input.ground_truth) anchors.push_back(view(s.pose.translation));
  std::vector<double> xs, ys;
  for (const MapPoint& p : map.map().points) {
    const Eigen::Vector2d q = view(p.position_in_map);
    xs.push_back(q.x());
    ys.push_back(q.y());
  }
  std::sort(xs.begin(), xs.end());
  std::sort(ys.begin(), ys.end());
  Eigen::AlignedBox2d box;
  for (const auto& a : anchors) box.extend(a);
  if (!xs.empty()) {
    box.extend(Eigen::Vector2d(xs[xs.size() / 100], ys[ys.size() / 100]));
    box.extend(Eigen::Vector2d(xs[xs.size() * 99 / 100], ys[ys.size() * 99 / 100]));
  }
  if (box.isEmpty()) box.extend(Eigen::Vector2d::Zero());
  box.extend(box.min() - Eigen::Vector2d::Constant(0.3));
  box.extend(box.max() + Eigen::Vector2d::Constant(0.3));
  const int size = 900, margin = 50;
  const double scale = (size - 2 * margin) / std::max(box.sizes().x(), box.sizes().y());
  const int width = static_cast<int>(box.sizes().x() * scale) + 2 * margin;
  const int height = static_cast<int>(box.sizes().y() * scale) + 2 * margin + 40;
  const auto px = [&](const Eigen::Vector3d& p) {
    const Eigen::Vector2d q = view(p);
    // Image y grows down; e2 points "up" on the page.
    return Eigen::Vector2d(margin + (q.x() - box.min().x()) * scale,
                           margin + 40 + (box.max().y() - q.y()) * scale);
  };
  const std::unique_ptr<Canvas> canvas = MakeCanvas(path, width, height);
  PlotStats stats;
  for (const MapPoint& p : map.map().points) {
    const Eigen::Vector2d q = px(p.position_in_map);
    if (q.x() < 0 || q.y() < 0 || q.x() > width || q.y() > height) continue;
    canvas->Dot(q.x(), q.y(), 1.0, {175, 175, 175});
    ++stats.points_drawn;
  }
  for (const auto& c : map.keyframe_centers()) {
    const Eigen::Vector2d q = px(c);
    canvas->Dot(q.x(), q.y(), 3.0, {40, 90, 220});
    ++stats.keyframes_drawn;
  }
  for (size_t i = 1; i < input.ground_truth.size(); ++i) {
    const Eigen::Vector2d a = px(input.ground_truth[i - 1].pose.translation);
    const Eigen::Vector2d b = px(input.ground_truth[i].pose.translation);
    canvas->Line(a.x(), a.y(), b.x(), b.y(), {215, 170, 235}, 7.0, false);
  }
  // A gap: more than 3 median frame intervals between consecutive estimates.
  std::vector<int64_t> steps;
  for (size_t i = 1; i < input.estimate.size(); ++i) {
    steps.push_back(input.estimate[i].timestamp_ns - input.estimate[i - 1].timestamp_ns);
  }
  std::nth_element(steps.begin(), steps.begin() + steps.size() / 2, steps.end());
  const int64_t gap_ns = steps.empty() ? 0 : 3 * steps[steps.size() / 2];
  for (size_t i = 1; i < input.estimate.size(); ++i) {
    const Eigen::Vector2d a = px(input.estimate[i - 1].pose.translation);
    const Eigen::Vector2d b = px(input.estimate[i].pose.translation);
    const bool gap = input.estimate[i].timestamp_ns - input.estimate[i - 1].timestamp_ns > gap_ns;
    const auto ratio = input.inlier_ratio.find(input.estimate[i].timestamp_ns);
    const Rgb color = gap                                 ? Rgb{90, 90, 90}
                      : ratio == input.inlier_ratio.end() ? Rgb{120, 120, 120}
                                                          : RatioColor(ratio->second);
    canvas->Line(a.x(), a.y(), b.x(), b.y(), color, 2.0, gap);
    (gap ? stats.gaps : stats.estimate_segments)++;
  }
  // Title, legend and a 1 m scale bar.
  canvas->Text(margin, 22, input.title, {20, 20, 20});
  canvas->Text(margin, 42,
               "grey: map points  blue: keyframes  violet: ground truth  estimate: inlier "
               "ratio red 0 - green 1, dashed: lost",
               {80, 80, 80});
  const double bar_y = height - 18;
  canvas->Line(width - margin - scale, bar_y, width - margin, bar_y, {20, 20, 20}, 2.0, false);
  canvas->Text(width - margin - scale, bar_y - 6, "1 m", {20, 20, 20});
  canvas->Save(path);
  return stats;
}

void WriteCurvePlot(const std::vector<Curve>& panels, const CurveAxes& axes,
                    const std::string& path) {
  VISLOC_CHECK(!panels.empty(), "no series to plot");
  const int width = 900, panel_height = 160, left = 70, right = 20, top = 40, gap = 40;
  const int height = top + static_cast<int>(panels.size()) * (panel_height + gap);
  const std::unique_ptr<Canvas> canvas = MakeCanvas(path, width, height);
  canvas->Text(left, 22, axes.title, {20, 20, 20});
  for (size_t p = 0; p < panels.size(); ++p) {
    const Curve& curve = panels[p];
    VISLOC_CHECK(curve.x.size() == curve.y.size(), "curve x and y differ in length");
    const auto x_scaled = [&](double x) { return axes.log_x ? std::log10(x) : x; };
    double min_x = std::numeric_limits<double>::max(), max_x = -min_x, max_y = 0.0;
    for (size_t i = 0; i < curve.x.size(); ++i) {
      if (!std::isfinite(curve.y[i]) || (axes.log_x && curve.x[i] <= 0)) continue;
      min_x = std::min(min_x, x_scaled(curve.x[i]));
      max_x = std::max(max_x, x_scaled(curve.x[i]));
      max_y = std::max(max_y, curve.y[i]);
    }
    if (max_y <= 0) max_y = 1.0;
    if (min_x > max_x) min_x = max_x = 0.0;   // Nothing to draw.
    if (max_x == min_x) max_x = min_x + 1.0;  // One point: a unit-wide axis around it.
    const double y0 = top + p * (panel_height + gap) + 18;  // Panel top.
    const auto x_of = [&](double x) {
      return left + (width - left - right) * (x_scaled(x) - min_x) / (max_x - min_x);
    };
    const auto y_of = [&](double v) { return y0 + panel_height * (1.0 - v / max_y); };
    canvas->Line(left, y0 + panel_height, width - right, y0 + panel_height, {120, 120, 120}, 1,
                 false);
    canvas->Line(left, y0, left, y0 + panel_height, {120, 120, 120}, 1, false);
    canvas->Text(left, y0 - 6, curve.title, {20, 20, 20});
    canvas->Text(8, y0 + 10, FormatFixed(max_y, max_y < 10 ? 2 : 0), {80, 80, 80});
    canvas->Text(8, y0 + panel_height, "0", {80, 80, 80});
    canvas->Text(width - right - 220, y0 + panel_height + 16, axes.x_label, {80, 80, 80});
    const bool markers = curve.x.size() <= 50;
    for (size_t i = 0; i < curve.x.size(); ++i) {
      if (!std::isfinite(curve.y[i]) || (axes.log_x && curve.x[i] <= 0)) continue;
      if (markers) {
        canvas->Dot(x_of(curve.x[i]), y_of(curve.y[i]), 3.5, {40, 90, 200});
        // Labels of the right half go to the left of their marker, to stay on the canvas.
        const double label_x =
            x_of(curve.x[i]) < width / 2 ? x_of(curve.x[i]) + 5 : x_of(curve.x[i]) - 110;
        canvas->Text(label_x, y_of(curve.y[i]) - 8,
                     StrCat(FormatFixed(curve.x[i], 0), ": ", FormatFixed(curve.y[i], 2)),
                     {60, 60, 60});
      }
      if (i == 0 || !std::isfinite(curve.y[i - 1])) continue;
      canvas->Line(x_of(curve.x[i - 1]), y_of(curve.y[i - 1]), x_of(curve.x[i]), y_of(curve.y[i]),
                   {40, 90, 200}, 1.5, false);
    }
  }
  canvas->Save(path);
}

void WriteSeriesPlot(const std::vector<Series>& panels, const std::string& title,
                     const std::string& path) {
  std::vector<Curve> curves;
  size_t frames = 0;
  for (const Series& series : panels) {
    Curve curve{series.title, {}, series.values};
    for (size_t i = 0; i < series.values.size(); ++i) curve.x.push_back(static_cast<double>(i));
    frames = std::max(frames, series.values.size());
    curves.push_back(std::move(curve));
  }
  WriteCurvePlot(curves, CurveAxes{title, StrCat("frame (", frames, " frames)"), false}, path);
}

}  // namespace visloc::cli
