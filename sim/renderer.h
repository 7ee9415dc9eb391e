#pragma once
// Exact rendering of the planar world by per-sample ray casting.
//
// Every image sample's viewing ray comes from the camera model (Camera::Unproject), so
// lens distortion, fisheye lenses included, is reproduced exactly and a 3D point's rendered
// position is where the camera model projects it. Each ray is intersected with every surface
// whose image footprint it lies in (ray-plane intersection, nearest hit wins: a z-buffer), the
// texture is sampled with a mip level matched to the sample's footprint (its angular spacing
// times the distance), and `supersample`^2 samples are averaged per pixel to anti-alias
// surface edges. With an exposure time, each of a pixel's samples sees the scene at its own
// instant of the exposure (distributed ray tracing), which blurs what moves across the image as
// a real shutter does. The result is radiance in [0, 1]; SensorModel turns it into an 8-bit
// image with exposure, gamma, vignetting and noise.

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
  // The same over an exposure of `exposure_s` centred on `time_s`, while the camera moves
  // (linearly in translation, along the shortest arc in rotation) from `world_from_cam_open`
  // to `world_from_cam_close`: motion blur.
  cv::Mat RenderRadiance(const World& world, const Rigid3d& world_from_cam_open,
                         const Rigid3d& world_from_cam_close, double time_s, double exposure_s,
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
  // The angle between neighbouring samples' rays (radians, geometric mean of the two image
  // directions): a fisheye samples angles about evenly, a pinhole ever more finely off axis.
  std::vector<float> sample_angle_;
  // The field of view in normalized coordinates: the range of ray_x_ and ray_y_.
  double fov_min_x_, fov_max_x_, fov_min_y_, fov_max_y_;
};

// The image sensor: radiance -> 8-bit grey.
//   value = 255 * clamp(exposure * vignette * radiance)^(1 / gamma) + noise,
// with Gaussian read noise and signal-dependent shot noise, rounded and clamped. The vignette
// darkens towards the corners as lenses do: 1 - vignetting (r / r_corner)^2, r the distance
// from the image centre.
struct SensorModel {
  double exposure = 1.0;
  double gamma = 1.0;
  double read_noise_dn = 1.2;     // Standard deviation in grey levels.
  double shot_noise_gain = 0.04;  // Variance per grey level of signal.
  double vignetting = 0.0;        // Light lost at the corners, in [0, 1).
  cv::Mat Capture(const cv::Mat& radiance, Rng* rng) const;
};

}  // namespace visloc::sim
