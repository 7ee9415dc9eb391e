// Reading a camera from its calibration's sensor.yaml, on the robot's side.
//
// The engine's reader (dataset/euroc.cc) uses yaml-cpp and engine types; a robot program links
// only visloc::client, so this one reads the same file with OpenCV's FileStorage (already a
// dependency through opencv_core) into the wire's CameraModel. A test holds the two readers to
// the same answers on every kind of file visloc writes and on real EuRoC calibrations.

#include <cmath>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <vector>

#include <opencv2/core.hpp>

#include "visloc/client/session.h"

namespace visloc::client {
namespace {

[[noreturn]] void Fail(const std::string& path, const std::string& what) {
  throw std::invalid_argument(path + ": " + what);
}

// OpenCV's YAML reader needs the "%YAML:1.0" directive EuRoC's files carry; visloc's own files
// (and hand-written ones) may lack it.
std::string ReadWithDirective(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) Fail(path, "no such file (or not readable)");
  std::stringstream text;
  text << in.rdbuf();
  const std::string body = text.str();
  return body.rfind("%YAML", 0) == 0 ? body : "%YAML:1.0\n" + body;
}

std::vector<double> Numbers(const std::string& path, const cv::FileNode& node,
                            const std::string& key, size_t expected) {
  if (node.empty()) Fail(path, "missing '" + key + "'");
  if (!node.isSeq() || node.size() != expected) {
    Fail(path, "'" + key + "' must be a list of " + std::to_string(expected) + " numbers");
  }
  std::vector<double> values;
  for (const cv::FileNode& item : node) {
    if (!item.isReal() && !item.isInt()) {
      Fail(path, "'" + key + "' has a non-number");
    }
    values.push_back(static_cast<double>(item));
  }
  return values;
}

std::string Text(const cv::FileNode& node) {
  return node.isString() ? static_cast<std::string>(node) : std::string();
}

v1::LensModel LensFrom(const std::string& path, const std::string& name) {
  if (name == "radial-tangential" || name == "radtan") return v1::RADIAL_TANGENTIAL;
  if (name == "equidistant") return v1::EQUIDISTANT;
  Fail(path, "unsupported distortion_model '" + name +
                 "' (expected radial-tangential, equidistant or none)");
}

// The unit quaternion of a rotation matrix (row-major), by its largest diagonal term for
// precision (Shepperd's method).
void SetRotation(const double r[3][3], v1::Pose* pose) {
  const double trace = r[0][0] + r[1][1] + r[2][2];
  double w, x, y, z;
  if (trace > 0) {
    const double s = 2.0 * std::sqrt(1.0 + trace);
    w = 0.25 * s, x = (r[2][1] - r[1][2]) / s, y = (r[0][2] - r[2][0]) / s,
    z = (r[1][0] - r[0][1]) / s;
  } else if (r[0][0] > r[1][1] && r[0][0] > r[2][2]) {
    const double s = 2.0 * std::sqrt(1.0 + r[0][0] - r[1][1] - r[2][2]);
    w = (r[2][1] - r[1][2]) / s, x = 0.25 * s, y = (r[0][1] + r[1][0]) / s,
    z = (r[0][2] + r[2][0]) / s;
  } else if (r[1][1] > r[2][2]) {
    const double s = 2.0 * std::sqrt(1.0 + r[1][1] - r[0][0] - r[2][2]);
    w = (r[0][2] - r[2][0]) / s, x = (r[0][1] + r[1][0]) / s, y = 0.25 * s,
    z = (r[1][2] + r[2][1]) / s;
  } else {
    const double s = 2.0 * std::sqrt(1.0 + r[2][2] - r[0][0] - r[1][1]);
    w = (r[1][0] - r[0][1]) / s, x = (r[0][2] + r[2][0]) / s, y = (r[1][2] + r[2][1]) / s,
    z = 0.25 * s;
  }
  const double norm = std::sqrt(w * w + x * x + y * y + z * z);
  pose->set_qw(w / norm);
  pose->set_qx(x / norm);
  pose->set_qy(y / norm);
  pose->set_qz(z / norm);
}

}  // namespace

v1::RigCamera RigCameraFromYaml(const std::string& path, const std::string& name) {
  v1::RigCamera rig_camera;
  *rig_camera.mutable_camera() = CameraFromYaml(path);
  rig_camera.set_name(name);
  cv::FileStorage file(ReadWithDirective(path), cv::FileStorage::READ | cv::FileStorage::MEMORY |
                                                    cv::FileStorage::FORMAT_YAML);
  const std::vector<double> t = Numbers(path, file["T_BS"]["data"], "T_BS.data", 16);
  double r[3][3];
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) r[i][j] = t[i * 4 + j];
  }
  // A rotation: its columns orthonormal (to a calibration file's printed precision).
  for (int a = 0; a < 3; ++a) {
    for (int b = 0; b < 3; ++b) {
      const double dot = r[0][a] * r[0][b] + r[1][a] * r[1][b] + r[2][a] * r[2][b];
      if (std::abs(dot - (a == b ? 1.0 : 0.0)) > 1e-3) Fail(path, "T_BS is not a rigid transform");
    }
  }
  v1::Pose* pose = rig_camera.mutable_body_from_cam();
  pose->set_tx(t[3]);
  pose->set_ty(t[7]);
  pose->set_tz(t[11]);
  SetRotation(r, pose);
  return rig_camera;
}

v1::CameraModel CameraFromYaml(const std::string& path) {
  cv::FileStorage file;
  try {
    file.open(ReadWithDirective(path), cv::FileStorage::READ | cv::FileStorage::MEMORY |
                                           cv::FileStorage::FORMAT_YAML);
  } catch (const cv::Exception& e) {
    Fail(path, "not a YAML file OpenCV can read (" + e.err + ")");
  }
  if (!file.isOpened()) Fail(path, "not a YAML file OpenCV can read");
  const std::string model = Text(file["camera_model"]);
  if (model.empty()) Fail(path, "missing 'camera_model'");
  if (model != "pinhole") Fail(path, "unsupported camera_model '" + model + "' (expected pinhole)");
  const std::vector<double> resolution = Numbers(path, file["resolution"], "resolution", 2);
  const std::vector<double> k = Numbers(path, file["intrinsics"], "intrinsics", 4);
  if (resolution[0] < 1 || resolution[1] < 1 || k[0] <= 0 || k[1] <= 0) {
    Fail(path, "invalid resolution or focal length");
  }
  v1::CameraModel camera = PinholeCamera(static_cast<int>(resolution[0]),
                                         static_cast<int>(resolution[1]), k[0], k[1], k[2], k[3]);
  const std::string lens = Text(file["distortion_model"]);
  if (!lens.empty() && lens != "none") {
    camera.set_lens_model(LensFrom(path, lens));
    for (double d : Numbers(path, file["distortion_coefficients"], "distortion_coefficients", 4)) {
      camera.add_distortion(d);
    }
  }
  return camera;
}

}  // namespace visloc::client
