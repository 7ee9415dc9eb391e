#pragma once
// Exact rendering of the planar world by per-sample ray casting.
//
// Every image sample's viewing ray comes from the camera model (Camera::Unproject), so
// lens distortion is reproduced exactly and a 3D point's rendered position is where the camera
// model projects it. Each ray is intersected with every surface whose image footprint it lies
// in (ray-plane intersection, nearest hit wins: a z-buffer), the texture is sampled with a
// footprint-matched mip level, and `supersample`^2 samples are averaged per pixel to
// anti-alias surface edges. The result is radiance in [0, 1]; SensorModel turns it into an
// 8-bit image with exposure, gamma and noise.

#include <vector>

#include <opencv2/core.hpp>

#include "core/camera/camera.h"
#include "core/geometry/rigid3.h"
#include "core/util/random.h"
#include "sim/world.h"

namespace visloc::sim {

class Renderer {
 public:
  // `supersample` samples per pixel side (1 = one ray through each pixel centre).
  Renderer(const Camera& camera, int supersample);

  // Radiance (CV_32FC1, [0, 1]) of `world` at `time_s` seen from `world_from_cam`. With
  // `depth`, also writes the z-depth (metres, CV_32FC1) of the sample nearest each pixel
  // centre, 0 where nothing was hit.
  cv::Mat RenderRadiance(const World& world, const Rigid3d& world_from_cam, double time_s,
                         cv::Mat* depth = nullptr) const;

  const Camera& camera() const { return camera_; }

 private:
  struct SampleRange {
    int x0, x1, y0, y1;  // Sample index bounds, half-open.
  };
  bool SurfaceRange(const Surface& surface_in_cam, SampleRange* range) const;

  Camera camera_;
  int supersample_;
  int samples_x_, samples_y_;
  std::vector<float> ray_x_, ray_y_;  // Viewing ray (x, y, 1) per sample, row-major.
  // The field of view in normalized coordinates: the range of ray_x_ and ray_y_.
  double fov_min_x_, fov_max_x_, fov_min_y_, fov_max_y_;
  float sample_spacing_;  // Sample spacing in normalized image units (1 / (f s)).
};

// The image sensor: radiance -> 8-bit grey.
//   value = 255 * clamp(exposure * radiance)^(1 / gamma) + noise,
// with Gaussian read noise and signal-dependent shot noise, rounded and clamped.
struct SensorModel {
  double exposure = 1.0;
  double gamma = 1.0;
  double read_noise_dn = 1.2;     // Standard deviation in grey levels.
  double shot_noise_gain = 0.04;  // Variance per grey level of signal.
  cv::Mat Capture(const cv::Mat& radiance, Rng* rng) const;
};

}  // namespace visloc::sim
