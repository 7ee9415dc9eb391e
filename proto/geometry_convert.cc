#include "proto/geometry_convert.h"

#include <algorithm>
#include <cmath>

#include "core/util/check.h"

namespace visloc::proto {
namespace {

// Plausible for any real camera: a focal length between a fortieth of the image size (wider than
// any fisheye's 180-250 degrees needs) and a hundred times it (a long telephoto).
constexpr double kMinFocalPerSize = 0.025, kMaxFocalPerSize = 100.0;
// Translations beyond this are not metres of a robot's world (1000 km).
constexpr double kMaxTranslationM = 1e6;

}  // namespace

// Refuses a wire value outside its allowed range, naming the field, the value and the range.
void RequireRange(const char* field, double value, double low, double high, const char* unit) {
  if (!(value >= low && value <= high)) {  // NaN fails both.
    throw InputError(
        StrCat(field, " is ", value, unit, "; allowed ", low, unit, " to ", high, unit));
  }
}

void ToProto(const Rigid3d& pose, v1::Pose* out) {
  out->set_tx(pose.translation.x());
  out->set_ty(pose.translation.y());
  out->set_tz(pose.translation.z());
  out->set_qw(pose.rotation.w());
  out->set_qx(pose.rotation.x());
  out->set_qy(pose.rotation.y());
  out->set_qz(pose.rotation.z());
}

Rigid3d FromProto(const v1::Pose& p, const char* field) {
  const Eigen::Vector3d t(p.tx(), p.ty(), p.tz());
  Eigen::Quaterniond q(p.qw(), p.qx(), p.qy(), p.qz());
  if (!t.allFinite() || t.cwiseAbs().maxCoeff() > kMaxTranslationM) {
    throw InputError(StrCat(field, ": translation (", t.x(), ", ", t.y(), ", ", t.z(),
                            ") must be finite and within ", kMaxTranslationM, " m"));
  }
  if (!q.coeffs().allFinite() || q.norm() < 1e-6) {
    throw InputError(StrCat(field, ": quaternion (w ", p.qw(), ", x ", p.qx(), ", y ", p.qy(),
                            ", z ", p.qz(), ") must be finite and non-zero (it is normalized)"));
  }
  q.normalize();
  return Rigid3d(q, t);
}

void ToProto(const Camera& camera, v1::CameraModel* out) {
  out->set_width(camera.width());
  out->set_height(camera.height());
  out->set_fx(camera.fx());
  out->set_fy(camera.fy());
  out->set_cx(camera.cx());
  out->set_cy(camera.cy());
  out->clear_distortion();
  for (double v : camera.lens().coefficients) out->add_distortion(v);
  out->set_lens_model(camera.lens().model == LensModel::kEquidistant ? v1::EQUIDISTANT
                                                                     : v1::RADIAL_TANGENTIAL);
}

Camera FromProto(const v1::CameraModel& c, const WireLimits& limits) {
  if (c.width() == 0 || c.height() == 0 ||
      c.width() > static_cast<uint32_t>(limits.max_image_width) ||
      c.height() > static_cast<uint32_t>(limits.max_image_height)) {
    throw InputError(StrCat("camera: size ", c.width(), "x", c.height(), " outside 1x1..",
                            limits.max_image_width, "x", limits.max_image_height));
  }
  const double size_px = std::max(c.width(), c.height());
  RequireRange("camera.fx", c.fx(), kMinFocalPerSize * size_px, kMaxFocalPerSize * size_px, " px");
  RequireRange("camera.fy", c.fy(), kMinFocalPerSize * size_px, kMaxFocalPerSize * size_px, " px");
  RequireRange("camera.cx", c.cx(), 0.0, c.width(), " px");
  RequireRange("camera.cy", c.cy(), 0.0, c.height(), " px");
  Lens lens;
  if (c.lens_model() == v1::EQUIDISTANT) {
    if (c.distortion_size() != 4) {
      throw InputError(
          StrCat("camera: an equidistant lens needs 4 distortion values (k1 k2 k3 k4), got ",
                 c.distortion_size()));
    }
    lens = Lens::Equidistant(c.distortion(0), c.distortion(1), c.distortion(2), c.distortion(3));
  } else if (c.lens_model() != v1::RADIAL_TANGENTIAL) {
    throw InputError(StrCat("camera: unknown lens model ", static_cast<int>(c.lens_model())));
  } else if (c.distortion_size() == 4) {
    lens = Lens(c.distortion(0), c.distortion(1), c.distortion(2), c.distortion(3));
  } else if (c.distortion_size() != 0) {
    throw InputError(
        StrCat("camera: distortion needs 0 or 4 values (k1 k2 p1 p2), got ", c.distortion_size()));
  }
  for (double k : lens.coefficients) RequireRange("camera.distortion", k, -100.0, 100.0);
  return Camera(static_cast<int>(c.width()), static_cast<int>(c.height()), c.fx(), c.fy(), c.cx(),
                c.cy(), lens);
}

void ToProto(const DisparityCorrection& correction, v1::DisparityCorrection* out) {
  out->set_offset_px(correction.offset_px);
  out->set_right_camera_yaw_deg(correction.yaw_deg());
}

DisparityCorrection FromProto(const v1::DisparityCorrection& correction) {
  return DisparityCorrection::FromDegrees(correction.offset_px(),
                                          correction.right_camera_yaw_deg());
}

}  // namespace visloc::proto
