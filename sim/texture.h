#pragma once
// Procedural surface textures for the synthetic world.
//
// A Texture is an albedo image in [0, 1] laid on a planar surface at `texel_size_m` metres per
// texel, sampled with trilinear mipmapping: the renderer passes the surface length one image
// sample covers (its footprint), and the matching pyramid level is used, so distant or
// oblique surfaces are low-pass filtered instead of aliasing into spurious corners.

#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>

namespace visloc::sim {

class Texture {
 public:
  // `albedo` is CV_8UC1 (0..255 maps to 0..1). Builds the mip pyramid.
  Texture(const cv::Mat& albedo, double texel_size_m);

  // Albedo at surface coordinates (u, v) in metres (origin at the surface's corner; u along
  // columns, v along rows). Coordinates outside the texture are clamped to its border.
  float Sample(double u_m, double v_m, double footprint_m) const;

  double width_m() const { return levels_[0].cols * texel_size_m_; }
  double height_m() const { return levels_[0].rows * texel_size_m_; }
  const cv::Mat& base() const { return levels_[0]; }

 private:
  float Bilinear(int level, double u_texels, double v_texels) const;
  std::vector<cv::Mat> levels_;  // CV_8UC1, each about half the previous size.
  // Each level's own texel size along u and v: sizes do not halve exactly when odd, and the
  // texture must stay in place on the surface at every level.
  std::vector<double> texel_u_m_, texel_v_m_;
  double texel_size_m_;
};

enum class TextureStyle {
  kPosterWall,  // Dense shapes at many scales: corners and blobs from 2 cm to 60 cm.
  kFloor,       // Tiles with grout lines, terrazzo speckles and a few marks.
  kCeiling,     // Light panels with a grid and light fixtures: sparse.
  kPlain,       // Painted wall: a faint gradient only (the low-texture stretch).
  kBox,         // Cardboard with tape and labels.
  kPerson,      // Clothing blocks for moving occluders.
};

// Generates the albedo image for a `width_m` x `height_m` surface. Deterministic in `seed`.
cv::Mat GenerateTexture(TextureStyle style, double width_m, double height_m, double texel_size_m,
                        uint64_t seed);

// Paints the rectangle [u0, u1] x [v0, v1] (metres) of an existing albedo image plain, as a
// freshly painted stretch of wall with only a faint gradient.
void PaintPlain(cv::Mat* albedo, double texel_size_m, double u0_m, double u1_m, double v0_m,
                double v1_m, uint64_t seed);

}  // namespace visloc::sim
