#pragma once
// Test-only: writes little-endian CDR (the layout cdr.h reads) and ROS 2 messages in it, to
// build ROS 2 bags for tests and fuzz seeds without ROS 2 installed.

#include <array>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace visloc::bag::testing {

class CdrWriter {
 public:
  CdrWriter() : bytes_{0, 1, 0, 0} {}
  CdrWriter& U8(uint8_t v) { return Put(&v, 1, 1); }
  CdrWriter& U32(uint32_t v) { return Put(&v, 4, 4); }
  CdrWriter& I32(int32_t v) { return Put(&v, 4, 4); }
  CdrWriter& F64(double v) { return Put(&v, 8, 8); }
  CdrWriter& String(const std::string& s) {
    U32(static_cast<uint32_t>(s.size() + 1));
    bytes_.insert(bytes_.end(), s.begin(), s.end());
    bytes_.push_back(0);
    return *this;
  }
  CdrWriter& Bytes(const std::string& data) {
    U32(static_cast<uint32_t>(data.size()));
    bytes_.insert(bytes_.end(), data.begin(), data.end());
    return *this;
  }
  CdrWriter& Header(int64_t stamp_ns, const std::string& frame_id) {
    I32(static_cast<int32_t>(stamp_ns / 1000000000));
    U32(static_cast<uint32_t>(stamp_ns % 1000000000));
    return String(frame_id);
  }
  std::string str() const { return std::string(bytes_.begin(), bytes_.end()); }

 private:
  CdrWriter& Put(const void* v, size_t size, size_t align) {
    while ((bytes_.size() - 4) % align) bytes_.push_back(0);
    const auto* p = static_cast<const char*>(v);
    bytes_.insert(bytes_.end(), p, p + size);
    return *this;
  }
  std::vector<char> bytes_;
};

inline std::string Ros2Image(int64_t stamp_ns, const cv::Mat& grey, const std::string& frame) {
  CdrWriter w;
  w.Header(stamp_ns, frame).U32(grey.rows).U32(grey.cols).String("mono8").U8(0).U32(grey.cols);
  std::string data;
  for (int y = 0; y < grey.rows; ++y) data.append(grey.ptr<char>(y), grey.cols);
  return w.Bytes(data).str();
}

inline std::string Ros2CompressedImage(int64_t stamp_ns, const std::string& format,
                                       const std::string& bytes, const std::string& frame) {
  CdrWriter w;
  return w.Header(stamp_ns, frame).String(format).Bytes(bytes).str();
}

// A pinhole camera_info; `baseline_m` > 0 makes it the right camera of a rectified pair.
inline std::string Ros2CameraInfo(int64_t stamp_ns, int width, int height, double f, double cx,
                                  double cy, const std::vector<double>& d, double baseline_m,
                                  const std::string& model = "plumb_bob") {
  CdrWriter w;
  w.Header(stamp_ns, "cam").U32(height).U32(width).String(model).U32(static_cast<uint32_t>(d.size()));
  for (double c : d) w.F64(c);
  const std::array<double, 9> k = {f, 0, cx, 0, f, cy, 0, 0, 1};
  const std::array<double, 9> r = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  const std::array<double, 12> p = {f, 0, cx, -f * baseline_m, 0, f, cy, 0, 0, 0, 1, 0};
  for (double v : k) w.F64(v);
  for (double v : r) w.F64(v);
  for (double v : p) w.F64(v);
  w.U32(0).U32(0);                              // binning
  w.U32(0).U32(0).U32(0).U32(0).U8(0);          // roi
  return w.str();
}

inline std::string Ros2Odometry(int64_t stamp_ns, const double xyz[3], const double xyzw[4]) {
  CdrWriter w;
  w.Header(stamp_ns, "odom").String("base_link");
  for (int i = 0; i < 3; ++i) w.F64(xyz[i]);
  for (int i = 0; i < 4; ++i) w.F64(xyzw[i]);
  for (int i = 0; i < 36 + 6 + 36; ++i) w.F64(0);  // covariance, twist, twist covariance
  return w.str();
}

}  // namespace visloc::bag::testing
