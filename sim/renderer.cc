#include "sim/renderer.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <opencv2/core/utility.hpp>

#include "core/util/check.h"

namespace visloc::sim {
namespace {

constexpr double kNearPlaneM = 0.02;

// A surface transformed into the camera frame, with what the inner loop needs precomputed.
struct CamSurface {
  Eigen::Vector3f origin, u_axis, v_axis, normal;
  float plane_d;  // normal . X = plane_d for points X on the plane.
  float origin_dot_u, origin_dot_v;
  float size_u, size_v;
  const Texture* texture;
  float shade;
};

}  // namespace

Renderer::Renderer(const Camera& camera, int supersample)
    : camera_(camera), supersample_(supersample) {
  VISLOC_CHECK(supersample >= 1 && supersample <= 8, "supersample ", supersample);
  samples_x_ = camera.width() * supersample;
  samples_y_ = camera.height() * supersample;
  const size_t count = static_cast<size_t>(samples_x_) * samples_y_;
  ray_x_.resize(count);
  ray_y_.resize(count);
  // Rays one sample further right and down, for the angular spacing.
  const auto ray_at = [&](double sx, double sy) {
    // Sample centres evenly spread inside pixel (px, py) = [px - 0.5, px + 0.5].
    const Eigen::Vector2d pixel(-0.5 + (sx + 0.5) / supersample, -0.5 + (sy + 0.5) / supersample);
    const Eigen::Vector3d ray = camera.Unproject(pixel);
    VISLOC_CHECK(ray.allFinite(), "the renderer needs every pixel's ray within 90 degrees of the ",
                 "optical axis: a field of view below 180 degrees across the diagonal");
    return ray;
  };
  sample_angle_.resize(count);
  for (int sy = 0; sy < samples_y_; ++sy) {
    for (int sx = 0; sx < samples_x_; ++sx) {
      const Eigen::Vector3d ray = ray_at(sx, sy);
      const size_t i = static_cast<size_t>(sy) * samples_x_ + sx;
      ray_x_[i] = static_cast<float>(ray.x());
      ray_y_[i] = static_cast<float>(ray.y());
      const Eigen::Vector3d unit = ray.normalized();
      const double across = std::acos(std::min(1.0, unit.dot(ray_at(sx + 1, sy).normalized())));
      const double down = std::acos(std::min(1.0, unit.dot(ray_at(sx, sy + 1).normalized())));
      sample_angle_[i] = static_cast<float>(std::sqrt(across * down));
    }
  }
  const auto [min_x, max_x] = std::minmax_element(ray_x_.begin(), ray_x_.end());
  const auto [min_y, max_y] = std::minmax_element(ray_y_.begin(), ray_y_.end());
  fov_min_x_ = *min_x;
  fov_max_x_ = *max_x;
  fov_min_y_ = *min_y;
  fov_max_y_ = *max_y;
}

bool Renderer::SurfaceRange(const Surface& s, SampleRange* range) const {
  // Bounds are found in undistorted normalized coordinates (x/z, y/z), where a planar polygon in
  // front of the camera stays a convex polygon, then clipped to the field of view, and only
  // then mapped to pixels. Mapping points far outside the field of view through the distortion
  // polynomial would be wrong: radial-tangential distortion is not monotonic there and folds
  // such points back into the image.
  const Eigen::Vector3d corners[4] = {s.origin, s.PointAt(s.size_u_m, 0),
                                      s.PointAt(s.size_u_m, s.size_v_m), s.PointAt(0, s.size_v_m)};
  double min_x = std::numeric_limits<double>::max(), min_y = min_x;
  double max_x = std::numeric_limits<double>::lowest(), max_y = max_x;
  bool any_in_front = false;
  auto add = [&](const Eigen::Vector3d& p) {
    any_in_front = true;
    min_x = std::min(min_x, p.x() / p.z());
    max_x = std::max(max_x, p.x() / p.z());
    min_y = std::min(min_y, p.y() / p.z());
    max_y = std::max(max_y, p.y() / p.z());
  };
  // Clip the rectangle against the near plane (Sutherland-Hodgman, one plane).
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector3d& a = corners[i];
    const Eigen::Vector3d& b = corners[(i + 1) % 4];
    const bool a_in = a.z() >= kNearPlaneM, b_in = b.z() >= kNearPlaneM;
    if (a_in) add(a);
    if (a_in != b_in) add(a + (kNearPlaneM - a.z()) / (b.z() - a.z()) * (b - a));
  }
  if (!any_in_front) return false;
  min_x = std::max(min_x, fov_min_x_);
  max_x = std::min(max_x, fov_max_x_);
  min_y = std::max(min_y, fov_min_y_);
  max_y = std::min(max_y, fov_max_y_);
  if (min_x > max_x || min_y > max_y) return false;
  // Within the field of view the lens mapping is monotonic, so the pixel bounds of the clipped
  // box's boundary bound its interior; the boundary is sampled densely because distortion
  // bends straight edges.
  double px_min_x = std::numeric_limits<double>::max(), px_min_y = px_min_x;
  double px_max_x = std::numeric_limits<double>::lowest(), px_max_y = px_max_x;
  constexpr int kPerEdge = 16;
  for (int k = 0; k <= kPerEdge; ++k) {
    const double fx = min_x + (max_x - min_x) * k / kPerEdge;
    const double fy = min_y + (max_y - min_y) * k / kPerEdge;
    for (const Eigen::Vector2d& n : {Eigen::Vector2d(fx, min_y), Eigen::Vector2d(fx, max_y),
                                     Eigen::Vector2d(min_x, fy), Eigen::Vector2d(max_x, fy)}) {
      Eigen::Vector2d pixel;
      camera_.Project(Eigen::Vector3d(n.x(), n.y(), 1.0), &pixel);
      px_min_x = std::min(px_min_x, pixel.x());
      px_max_x = std::max(px_max_x, pixel.x());
      px_min_y = std::min(px_min_y, pixel.y());
      px_max_y = std::max(px_max_y, pixel.y());
    }
  }
  const double margin = 1.0;
  const int f = supersample_;
  range->x0 =
      std::clamp(static_cast<int>(std::floor((px_min_x - margin + 0.5) * f)), 0, samples_x_);
  range->x1 = std::clamp(static_cast<int>(std::ceil((px_max_x + margin + 0.5) * f)), 0, samples_x_);
  range->y0 =
      std::clamp(static_cast<int>(std::floor((px_min_y - margin + 0.5) * f)), 0, samples_y_);
  range->y1 = std::clamp(static_cast<int>(std::ceil((px_max_y + margin + 0.5) * f)), 0, samples_y_);
  return range->x0 < range->x1 && range->y0 < range->y1;
}

cv::Mat Renderer::RenderRadiance(const World& world, const Rigid3d& world_from_cam, double time_s,
                                 cv::Mat* depth) const {
  return RenderRadiance(world, world_from_cam, world_from_cam, time_s, 0.0, depth);
}

cv::Mat Renderer::RenderRadiance(const World& world, const Rigid3d& world_from_cam_open,
                                 const Rigid3d& world_from_cam_close, double time_s,
                                 double exposure_s, cv::Mat* depth) const {
  VISLOC_CHECK(exposure_s >= 0, "exposure ", exposure_s);
  const int s = supersample_;
  // Time slots: one per sample of a pixel during an exposure (sample (sx, sy) takes slot
  // (sy % s) s + (sx % s)), or a single instant.
  const int slots = exposure_s > 0 && s > 1 ? s * s : 1;
  std::vector<CamSurface> cam_surfaces;
  std::vector<SampleRange> ranges;
  std::vector<int> slot_of;
  for (int slot = 0; slot < slots; ++slot) {
    const double fraction = slots == 1 ? 0.5 : (slot + 0.5) / slots;
    const Rigid3d world_from_cam(
        world_from_cam_open.rotation.slerp(fraction, world_from_cam_close.rotation),
        (1 - fraction) * world_from_cam_open.translation +
            fraction * world_from_cam_close.translation);
    const Rigid3d cam_from_world = world_from_cam.Inverse();
    for (const Surface& surface : world.SurfacesAt(time_s + (fraction - 0.5) * exposure_s)) {
      Surface in_cam = surface;
      in_cam.origin = cam_from_world * surface.origin;
      in_cam.u_axis = cam_from_world.rotation * surface.u_axis;
      in_cam.v_axis = cam_from_world.rotation * surface.v_axis;
      SampleRange range;
      if (!SurfaceRange(in_cam, &range)) continue;
      CamSurface c;
      c.origin = in_cam.origin.cast<float>();
      c.u_axis = in_cam.u_axis.cast<float>();
      c.v_axis = in_cam.v_axis.cast<float>();
      c.normal = c.u_axis.cross(c.v_axis);
      c.plane_d = c.normal.dot(c.origin);
      c.origin_dot_u = c.origin.dot(c.u_axis);
      c.origin_dot_v = c.origin.dot(c.v_axis);
      c.size_u = static_cast<float>(surface.size_u_m);
      c.size_v = static_cast<float>(surface.size_v_m);
      c.texture = world.textures.at(surface.texture).get();
      c.shade = surface.shade;
      cam_surfaces.push_back(c);
      ranges.push_back(range);
      slot_of.push_back(slot);
    }
  }
  VISLOC_CHECK(cam_surfaces.size() < 32768, "too many surfaces in view: ", cam_surfaces.size());

  // Pass 1: visibility. Per sample, the nearest surface hit (z-buffer on depth along z).
  const size_t sample_count = ray_x_.size();
  std::vector<float> zbuffer(sample_count, std::numeric_limits<float>::infinity());
  std::vector<int16_t> hit(sample_count, -1);
  for (size_t k = 0; k < cam_surfaces.size(); ++k) {
    const CamSurface& c = cam_surfaces[k];
    const SampleRange& r = ranges[k];
    // The samples of this surface's time slot: every s-th from the slot's offset.
    const int step = slots == 1 ? 1 : s;
    const int offset_x = slots == 1 ? 0 : slot_of[k] % s, offset_y = slots == 1 ? 0 : slot_of[k] / s;
    const auto first = [&](int from, int offset) { return from + ((offset - from % step) % step + step) % step; };
    for (int sy = first(r.y0, offset_y); sy < r.y1; sy += step) {
      const size_t row = static_cast<size_t>(sy) * samples_x_;
      for (int sx = first(r.x0, offset_x); sx < r.x1; sx += step) {
        const size_t i = row + sx;
        const float rx = ray_x_[i], ry = ray_y_[i];
        const float denom = c.normal.x() * rx + c.normal.y() * ry + c.normal.z();
        if (std::abs(denom) < 1e-7f) continue;
        const float z = c.plane_d / denom;
        if (z <= kNearPlaneM || z >= zbuffer[i]) continue;
        const float a = z * (rx * c.u_axis.x() + ry * c.u_axis.y() + c.u_axis.z()) - c.origin_dot_u;
        const float b = z * (rx * c.v_axis.x() + ry * c.v_axis.y() + c.v_axis.z()) - c.origin_dot_v;
        if (a < 0.0f || b < 0.0f || a > c.size_u || b > c.size_v) continue;
        zbuffer[i] = z;
        hit[i] = static_cast<int16_t>(k);
      }
    }
  }

  // Pass 2: shading, parallel over pixel rows (deterministic: no shared random state).
  cv::Mat radiance(camera_.height(), camera_.width(), CV_32FC1);
  const float inv_samples = 1.0f / (s * s);
  cv::parallel_for_(cv::Range(0, camera_.height()), [&](const cv::Range& rows) {
    for (int py = rows.start; py < rows.end; ++py) {
      float* out = radiance.ptr<float>(py);
      for (int px = 0; px < camera_.width(); ++px) {
        float sum = 0.0f;
        for (int sy = py * s; sy < (py + 1) * s; ++sy) {
          for (int sx = px * s; sx < (px + 1) * s; ++sx) {
            const size_t i = static_cast<size_t>(sy) * samples_x_ + sx;
            if (hit[i] < 0) continue;
            const CamSurface& c = cam_surfaces[hit[i]];
            const float rx = ray_x_[i], ry = ray_y_[i], z = zbuffer[i];
            const float a =
                z * (rx * c.u_axis.x() + ry * c.u_axis.y() + c.u_axis.z()) - c.origin_dot_u;
            const float b =
                z * (rx * c.v_axis.x() + ry * c.v_axis.y() + c.v_axis.z()) - c.origin_dot_v;
            // Footprint of one sample on the surface: distance times the angular spacing,
            // stretched by the obliqueness (geometric mean of the two axes' stretch).
            const float ray_norm = std::sqrt(rx * rx + ry * ry + 1.0f);
            const float cos_incidence = std::max(
                std::abs(c.normal.x() * rx + c.normal.y() * ry + c.normal.z()) / ray_norm, 0.05f);
            const float footprint = z * ray_norm * sample_angle_[i] / std::sqrt(cos_incidence);
            sum += c.shade * c.texture->Sample(a, b, footprint);
          }
        }
        out[px] = sum * inv_samples;
      }
    }
  });

  if (depth != nullptr) {
    *depth = cv::Mat(camera_.height(), camera_.width(), CV_32FC1);
    for (int py = 0; py < camera_.height(); ++py) {
      for (int px = 0; px < camera_.width(); ++px) {
        const size_t i = static_cast<size_t>(py * s + s / 2) * samples_x_ + px * s + s / 2;
        depth->at<float>(py, px) = hit[i] < 0 ? 0.0f : zbuffer[i];
      }
    }
  }
  return radiance;
}

cv::Mat SensorModel::Capture(const cv::Mat& radiance, Rng* rng) const {
  VISLOC_CHECK(radiance.type() == CV_32FC1, "radiance must be CV_32FC1");
  VISLOC_CHECK(exposure > 0 && gamma > 0, "exposure ", exposure, " gamma ", gamma);
  VISLOC_CHECK(vignetting >= 0 && vignetting < 1, "vignetting ", vignetting);
  cv::Mat image(radiance.size(), CV_8UC1);
  const double inv_gamma = 1.0 / gamma;
  const double cx = 0.5 * (radiance.cols - 1), cy = 0.5 * (radiance.rows - 1);
  const double inv_corner_sq = 1.0 / (cx * cx + cy * cy);
  for (int r = 0; r < radiance.rows; ++r) {
    const float* in = radiance.ptr<float>(r);
    uint8_t* out = image.ptr<uint8_t>(r);
    for (int c = 0; c < radiance.cols; ++c) {
      const double falloff =
          1.0 - vignetting * ((c - cx) * (c - cx) + (r - cy) * (r - cy)) * inv_corner_sq;
      const double signal =
          255.0 * std::pow(std::clamp(exposure * falloff * in[c], 0.0, 1.0), inv_gamma);
      const double sigma = std::sqrt(read_noise_dn * read_noise_dn + shot_noise_gain * signal);
      const double value = signal + (sigma > 0 ? rng->Normal(0.0, sigma) : 0.0);
      out[c] = static_cast<uint8_t>(std::clamp(std::lround(value), 0L, 255L));
    }
  }
  return image;
}

}  // namespace visloc::sim
