#include "ros/messages/ros_messages.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <map>

#include <Eigen/Geometry>
#include <opencv2/imgproc.hpp>

#include "core/image/image_codec.h"
#include "core/util/check.h"

namespace visloc::ros_msg {
namespace {

// OpenCV names a Bayer pattern by the second row's first two pixels, ROS by the first row's:
// ROS's rggb is OpenCV's BG (as cv_bridge converts them).
const std::map<std::string, int>& BayerCodes() {
  static const std::map<std::string, int> codes = {
      {"bayer_rggb8", cv::COLOR_BayerBG2GRAY},
      {"bayer_bggr8", cv::COLOR_BayerRG2GRAY},
      {"bayer_gbrg8", cv::COLOR_BayerGR2GRAY},
      {"bayer_grbg8", cv::COLOR_BayerGB2GRAY},
  };
  return codes;
}

struct EncodingLayout {
  int cv_type;
  int bytes_per_pixel;
  int to_grey;  // cv::cvtColor code; -1: none (grey already), -2: 16-bit grey to scale.
};

EncodingLayout LayoutOf(const std::string& encoding) {
  if (encoding == "mono8" || encoding == "8UC1") return {CV_8UC1, 1, -1};
  if (encoding == "mono16" || encoding == "16UC1") return {CV_16UC1, 2, -2};
  if (encoding == "rgb8") return {CV_8UC3, 3, cv::COLOR_RGB2GRAY};
  if (encoding == "bgr8" || encoding == "8UC3") return {CV_8UC3, 3, cv::COLOR_BGR2GRAY};
  if (encoding == "rgba8") return {CV_8UC4, 4, cv::COLOR_RGBA2GRAY};
  if (encoding == "bgra8" || encoding == "8UC4") return {CV_8UC4, 4, cv::COLOR_BGRA2GRAY};
  auto bayer = BayerCodes().find(encoding);
  if (bayer != BayerCodes().end()) return {CV_8UC1, 1, bayer->second};
  throw InputError(StrCat("image encoding '", encoding,
                          "' is not supported (mono8, mono16, rgb8, bgr8, rgba8, bgra8, "
                          "bayer_*8)"));
}

}  // namespace

std::string StampText(int64_t stamp_ns) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.9f", static_cast<double>(stamp_ns) * 1e-9);
  return text;
}

std::string NormalizeTypeName(const std::string& type) {
  static const char* const kKnown[] = {"sensor_msgs/Image", "sensor_msgs/CompressedImage",
                                       "sensor_msgs/CameraInfo", "sensor_msgs/Imu",
                                       "nav_msgs/Odometry"};
  std::string name = type;
  const size_t msg = name.find("/msg/");
  if (msg != std::string::npos) name.erase(msg, 4);
  for (const char* known : kKnown) {
    if (name == known) return name;
  }
  return "";
}

cv::Mat DecodeRawImage(int64_t width, int64_t height, const std::string& encoding,
                       bool is_bigendian, int64_t step, std::string_view data) {
  if (width <= 0 || height <= 0 || width > 16384 || height > 16384) {
    throw InputError(StrCat("image size ", width, "x", height, " is not plausible"));
  }
  const int rows = static_cast<int>(height), cols = static_cast<int>(width);  // Checked above.
  const EncodingLayout layout = LayoutOf(encoding);
  const int64_t row_bytes = static_cast<int64_t>(width) * layout.bytes_per_pixel;
  if (step < row_bytes) {
    throw InputError(StrCat("image step ", step, " bytes is shorter than a ", encoding, " row of ",
                            row_bytes, " bytes"));
  }
  if (static_cast<int64_t>(data.size()) < step * (height - 1) + row_bytes) {
    throw InputError(StrCat("image has ", data.size(), " bytes; ", width, "x", height, " ",
                            encoding, " with step ", step, " needs ",
                            step * (height - 1) + row_bytes));
  }
  // The rows, packed: a message's step need not be a multiple of the pixel size (cv::Mat's
  // own step must), and the copy leaves the message's bytes untouched.
  cv::Mat view(rows, cols, layout.cv_type);
  for (int y = 0; y < rows; ++y) {
    std::memcpy(view.ptr(y), data.data() + static_cast<int64_t>(y) * step, row_bytes);
  }
  cv::Mat grey;
  if (layout.to_grey == -1) {
    grey = view;
  } else if (layout.to_grey == -2) {
    cv::Mat& wide = view;
    const bool host_big_endian = cv::Mat(1, 1, CV_16UC1, cv::Scalar(1)).data[0] == 0;
    if (is_bigendian != host_big_endian) {
      for (int y = 0; y < rows; ++y) {
        auto* row = wide.ptr<uint16_t>(y);
        for (int x = 0; x < cols; ++x)
          row[x] = static_cast<uint16_t>((row[x] << 8) | (row[x] >> 8));
      }
    }
    wide.convertTo(grey, CV_8U, 1.0 / 256.0);
  } else {
    cv::cvtColor(view, grey, layout.to_grey);
  }
  return grey;
}

Rigid3d OdometryPose(const Eigen::Quaterniond& orientation, const Eigen::Vector3d& position) {
  if (!(orientation.norm() > 1e-6)) {
    throw InputError("nav_msgs/Odometry pose.pose.orientation is not a rotation (zero norm)");
  }
  return Rigid3d(orientation.normalized(), position);
}

cv::Mat DecodeCompressedImage(const std::string& format, std::string_view data) {
  if (data.empty()) throw InputError("compressed image has no data");
  std::string why;
  cv::Mat grey = image::DecodeGrey(data.data(), data.size(), &why);
  if (grey.empty()) {
    throw InputError(
        StrCat("compressed image (format '", format, "', ", data.size(), " bytes): ", why));
  }
  return grey;
}

namespace {

// The largest normalized radius of the image: its farthest corner from the principal point.
double CornerRadius(const CameraInfoMessage& info) {
  double r = 0.0;
  for (int x : {0, info.width - 1}) {
    for (int y : {0, info.height - 1}) {
      r = std::max(r, std::hypot((x - info.k[2]) / info.k[0], (y - info.k[5]) / info.k[4]));
    }
  }
  return r;
}

// plumb_bob: k1 k2 p1 p2 [k3]; rational_polynomial: k1 k2 p1 p2 k3 k4 k5 k6 (the radial factor
// (1 + k1 r^2 + k2 r^4 + k3 r^6) / (1 + k4 r^2 + k5 r^4 + k6 r^6)). visloc keeps k1 k2 p1 p2;
// the pixels the rest moves the farthest corner by say whether dropping it is harmless.
Lens RadialTangentialLens(const CameraInfoMessage& info, const std::string& topic,
                          double max_dropped_term_px) {
  const std::vector<double>& d = info.d;
  if (d.size() < 4) {
    throw InputError(StrCat(topic, ": ", info.distortion_model, " needs at least 4 coefficients, ",
                            "the camera_info has ", d.size()));
  }
  auto coefficient = [&](size_t i) { return i < d.size() ? d[i] : 0.0; };
  const double r = CornerRadius(info);
  const double r2 = r * r;
  const double kept = 1 + d[0] * r2 + d[1] * r2 * r2;
  const double full =
      (kept + coefficient(4) * r2 * r2 * r2) /
      (1 + coefficient(5) * r2 + coefficient(6) * r2 * r2 + coefficient(7) * r2 * r2 * r2);
  const double dropped_px = std::abs(full - kept) * r * std::max(info.k[0], info.k[4]);
  if (!(dropped_px <= max_dropped_term_px)) {
    throw InputError(StrCat(topic, ": the ", info.distortion_model,
                            " terms beyond k1 k2 p1 p2 move the image corner by ", dropped_px,
                            " px; visloc's radial-tangential model has no k3..k6. Calibrate "
                            "without them (visloc calibrate) or give a sensor.yaml"));
  }
  return Lens(d[0], d[1], d[2], d[3]);
}

Eigen::Matrix3d RotationOf(const std::array<double, 9>& r) {
  Eigen::Matrix3d m;
  for (int i = 0; i < 9; ++i) m(i / 3, i % 3) = r[i];
  if (m.isZero()) return Eigen::Matrix3d::Identity();  // An unrectified (monocular) camera.
  if (!(m * m.transpose()).isApprox(Eigen::Matrix3d::Identity(), 1e-6) || m.determinant() < 0) {
    throw InputError("camera_info R is not a rotation matrix");
  }
  return m;
}

}  // namespace

Camera CameraFromInfo(const CameraInfoMessage& info, const std::string& topic,
                      double max_dropped_term_px) {
  if (info.width <= 0 || info.height <= 0) {
    throw InputError(
        StrCat(topic, ": camera_info has no image size (", info.width, "x", info.height, ")"));
  }
  const double fx = info.k[0], fy = info.k[4], cx = info.k[2], cy = info.k[5];
  if (!(fx > 0 && fy > 0 && std::isfinite(cx) && std::isfinite(cy))) {
    throw InputError(StrCat(topic, ": camera_info K has no focal length (fx ", fx, ", fy ", fy,
                            "): the camera is not calibrated"));
  }
  Lens lens;
  const std::string& model = info.distortion_model;
  if (model == "equidistant") {
    if (info.d.size() != 4) {
      throw InputError(
          StrCat(topic, ": equidistant needs 4 coefficients, the camera_info has ", info.d.size()));
    }
    lens = Lens::Equidistant(info.d[0], info.d[1], info.d[2], info.d[3]);
  } else if (model == "plumb_bob" || model == "rational_polynomial") {
    lens = RadialTangentialLens(info, topic, max_dropped_term_px);
  } else if (model.empty() &&
             std::all_of(info.d.begin(), info.d.end(), [](double c) { return c == 0.0; })) {
    lens = Lens();  // No model and no coefficients: a distortion-free (e.g. rectified) camera.
  } else {
    throw InputError(StrCat(topic, ": distortion model '", model,
                            "' is not supported (plumb_bob, rational_polynomial, equidistant)"));
  }
  return Camera(info.width, info.height, fx, fy, cx, cy, lens);
}

Rigid3d LeftFromRight(const CameraInfoMessage& left, const CameraInfoMessage& right) {
  const double fx_rect = right.p[0];
  if (!(fx_rect > 0) || right.p[3] == 0.0) {
    throw InputError(
        "the right camera_info's P carries no baseline (P[3] = -fx' * baseline is 0): the "
        "cameras are not a calibrated stereo pair; give --left-yaml and --right-yaml");
  }
  const double baseline_m = -right.p[3] / fx_rect;
  if (baseline_m < 0) {
    throw InputError(StrCat("the right camera_info's P says the right camera is ", -baseline_m,
                            " m to the left of the left one: are --left and --right swapped?"));
  }
  const Eigen::Matrix3d rect_from_left = RotationOf(left.r);
  const Eigen::Matrix3d rect_from_right = RotationOf(right.r);
  // A point p in the right camera is at rect_from_right p + (baseline, 0, 0) in the left
  // camera's rectified frame.
  return Rigid3d(Eigen::Matrix3d(rect_from_left.transpose() * rect_from_right),
                 rect_from_left.transpose() * Eigen::Vector3d(baseline_m, 0, 0));
}

}  // namespace visloc::ros_msg
