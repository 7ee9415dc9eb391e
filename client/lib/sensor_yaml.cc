// Reading a camera from its calibration's sensor.yaml, on the robot's side.
//
// The engine's reader (dataset/euroc.cc) uses yaml-cpp and engine types; a robot program links
// only visloc::client, so this one reads the same file with OpenCV's FileStorage (already a
// dependency through opencv_core) into the wire's CameraModel. A test holds the two readers to
// the same answers on every kind of file visloc writes and on real EuRoC calibrations.

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

}  // namespace

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
