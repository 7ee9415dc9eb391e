#include "mapping/stereo_frame.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>

#include "core/util/check.h"

namespace visloc::mapping {

void StereoMatchOptions::Check() const {
  matching.Check();
  VISLOC_CHECK(max_row_difference_px > 0 && min_depth_m > 0 && max_depth_m > min_depth_m,
               "stereo limits: rows ", max_row_difference_px, " px, depth ", min_depth_m, "-",
               max_depth_m, " m");
  VISLOC_CHECK(refine_patch_radius_px >= 0 && refine_max_shift_px > 0, "disparity refinement ",
               refine_patch_radius_px, " px, ", refine_max_shift_px, " px");
}

namespace {

// Cell of the frames' keypoint grids; radius searches of any size visit the cells they touch.
constexpr int kGridCellPx = 16;

inline float Bilinear(const cv::Mat& image, double x, double y) {
  const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
  const float fx = static_cast<float>(x - x0), fy = static_cast<float>(y - y0);
  const float* r0 = image.ptr<float>(y0);
  const float* r1 = image.ptr<float>(y0 + 1);
  return (1 - fy) * ((1 - fx) * r0[x0] + fx * r0[x0 + 1]) +
         fy * ((1 - fx) * r1[x0] + fx * r1[x0 + 1]);
}

}  // namespace

bool RefineDisparity(const cv::Mat& left, const cv::Mat& right, const cv::Mat& right_gradient_x,
                     double x, double y, int radius, double* d) {
  const int margin = radius + 2;
  if (x < margin || y < margin || x >= left.cols - margin || y >= left.rows - margin) return false;
  const int n = (2 * radius + 1) * (2 * radius + 1);
  std::vector<float> template_values(n);
  double template_mean = 0;
  int k = 0;
  for (int v = -radius; v <= radius; ++v) {
    for (int u = -radius; u <= radius; ++u, ++k) {
      template_values[k] = Bilinear(left, x + u, y + v);
      template_mean += template_values[k];
    }
  }
  template_mean /= n;
  // Disparity varies across the patch on slanted surfaces (the floor, the ceiling), so it is
  // modelled as d(u, v) = d0 + gu u + gv v over patch offsets (u, v); d0 is the disparity at the
  // patch centre. A pure shift would absorb the gradient as a bias.
  Eigen::Vector3d params(*d, 0.0, 0.0);
  std::vector<float> values(n), gradients(n);
  for (int iteration = 0; iteration < 10; ++iteration) {
    double mean = 0;
    k = 0;
    for (int v = -radius; v <= radius; ++v) {
      for (int u = -radius; u <= radius; ++u, ++k) {
        const double xr = x + u - (params[0] + params[1] * u + params[2] * v);
        if (xr < 1 || xr >= right.cols - 2) return false;
        values[k] = Bilinear(right, xr, y + v);
        gradients[k] = Bilinear(right_gradient_x, xr, y + v);
        mean += values[k];
      }
    }
    mean /= n;
    // r_k = (I_r(x + u - d(u, v)) - mean_r) - (I_l(x + u) - mean_l); dr/dparams = -g_k (1, u, v).
    Eigen::Matrix3d jtj = Eigen::Matrix3d::Zero();
    Eigen::Vector3d jtr = Eigen::Vector3d::Zero();
    k = 0;
    for (int v = -radius; v <= radius; ++v) {
      for (int u = -radius; u <= radius; ++u, ++k) {
        const double r = (values[k] - mean) - (template_values[k] - template_mean);
        const Eigen::Vector3d j = -gradients[k] * Eigen::Vector3d(1.0, u, v);
        jtj += j * j.transpose();
        jtr += j * r;
      }
    }
    if (jtj(0, 0) < 1e-9) return false;
    jtj.diagonal() +=
        Eigen::Vector3d(0, 1e-3, 1e-3) * jtj(0, 0);  // keep gradients small unless needed
    const Eigen::Vector3d step = jtj.ldlt().solve(-jtr);
    if (!step.allFinite()) return false;
    params += step;
    if (std::abs(step[0]) < 1e-3) break;
  }
  if (std::abs(params[1]) > 0.5 || std::abs(params[2]) > 0.5) return false;  // not a surface
  *d = params[0];
  return true;
}

StereoFrame BuildStereoFrame(const cv::Mat& left_raw, const cv::Mat& right_raw,
                             const FeatureExtractor& extractor, const StereoRectifier& rectifier,
                             const StereoMatchOptions& options) {
  options.Check();
  StereoFrame frame;
  frame.left = extractor.Extract(left_raw);
  const FeatureSet right = extractor.Extract(right_raw);
  const PinholeCamera& rect = rectifier.rectified_camera();
  const double f = rect.fx(), baseline = rectifier.baseline_m();
  const double min_disparity = f * baseline / options.max_depth_m;
  const double max_disparity = f * baseline / options.min_depth_m;
  const float max_distance = options.matching.MaxDistance(extractor.settings().descriptor_type);

  const size_t n = frame.left.size();
  frame.left_rect.resize(n);
  std::vector<Eigen::Vector2f> grid_pixels(n);
  for (size_t i = 0; i < n; ++i) {
    frame.left_rect[i] = rectifier.RectifyLeftPixel(frame.left.keypoints[i].pixel.cast<double>());
    grid_pixels[i] = frame.left_rect[i].cast<float>();
  }
  frame.grid = KeypointGrid(std::move(grid_pixels), rect.width(), rect.height(), kGridCellPx);
  // Right keypoints sorted by rectified row for a band search.
  std::vector<std::pair<double, int>> right_rows;
  std::vector<Eigen::Vector2d> right_rect(right.size());
  for (size_t j = 0; j < right.size(); ++j) {
    right_rect[j] = rectifier.RectifyRightPixel(right.keypoints[j].pixel.cast<double>());
    right_rows.emplace_back(right_rect[j].y(), static_cast<int>(j));
  }
  std::sort(right_rows.begin(), right_rows.end());

  // Best right candidate per left keypoint (ratio test), then a mutual check.
  std::vector<int> left_to_right(n, -1);
  std::vector<int> right_best_left(right.size(), -1);
  std::vector<float> right_best_distance(right.size(), std::numeric_limits<float>::max());
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector2d& l = frame.left_rect[i];
    auto it = std::lower_bound(right_rows.begin(), right_rows.end(),
                               std::make_pair(l.y() - options.max_row_difference_px, -1));
    NearestTwo nearest;
    for (; it != right_rows.end() && it->first <= l.y() + options.max_row_difference_px; ++it) {
      const int j = it->second;
      const double disparity = l.x() - right_rect[j].x();
      if (disparity < min_disparity || disparity > max_disparity) continue;
      nearest.Offer(
          DescriptorDistance(frame.left.descriptors, static_cast<int>(i), right.descriptors, j), j);
    }
    if (!nearest.Distinctive(options.matching.ratio, max_distance)) continue;
    const int best_j = nearest.best_index;
    const float best = nearest.best;
    left_to_right[i] = best_j;
    if (best < right_best_distance[best_j]) {
      right_best_distance[best_j] = best;
      right_best_left[best_j] = static_cast<int>(i);
    }
  }

  cv::Mat left_rect_image, right_rect_image, right_gradient_x;
  if (options.refine_patch_radius_px > 0) {
    cv::Mat left_8u, right_8u;
    rectifier.Rectify(left_raw, right_raw, &left_8u, &right_8u);
    left_8u.convertTo(left_rect_image, CV_32F);
    right_8u.convertTo(right_rect_image, CV_32F);
    // Central difference, as the alignment's linearization assumes.
    const cv::Mat kernel = (cv::Mat_<float>(1, 3) << -0.5f, 0.0f, 0.5f);
    cv::filter2D(right_rect_image, right_gradient_x, CV_32F, kernel, cv::Point(-1, -1), 0,
                 cv::BORDER_REPLICATE);
  }
  const double nan = std::numeric_limits<double>::quiet_NaN();
  frame.right_x_rect.assign(n, nan);
  frame.point_in_rect.assign(n, Eigen::Vector3d::Constant(nan));
  for (size_t i = 0; i < n; ++i) {
    const int j = left_to_right[i];
    if (j < 0 || right_best_left[j] != static_cast<int>(i)) continue;
    const Eigen::Vector2d& l = frame.left_rect[i];
    double disparity = l.x() - right_rect[j].x();
    if (options.refine_patch_radius_px > 0) {
      double refined = disparity;
      if (!RefineDisparity(left_rect_image, right_rect_image, right_gradient_x, l.x(), l.y(),
                           options.refine_patch_radius_px, &refined) ||
          std::abs(refined - disparity) > options.refine_max_shift_px || refined < min_disparity ||
          refined > max_disparity) {
        continue;
      }
      disparity = refined;
    }
    const double v = l.y();
    const double z = f * baseline / disparity;
    frame.right_x_rect[i] = l.x() - disparity;
    frame.point_in_rect[i] =
        Eigen::Vector3d((l.x() - rect.cx()) * z / f, (v - rect.cy()) * z / rect.fy(), z);
    ++frame.stereo_matches;
  }
  return frame;
}

}  // namespace visloc::mapping
