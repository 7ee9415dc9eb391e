#pragma once
// What `visloc` asks of a camera, a GStreamer pipeline or a video file, and the entry point of
// the module that provides it (video_capture_module.cc, through OpenCV's videoio).
//
// Why a module loaded on demand: Debian's libopencv_videoio links GStreamer and FFmpeg (245
// shared libraries with imgcodecs). Linked into `visloc`, every command paid for loading them at
// start, 0.15 s of a `visloc --version`; only `stream --camera` and `map build --camera` read
// a camera. The module is built with the CLI and installed beside it (VideoSource finds it).

#include <string>

#include <opencv2/core.hpp>

namespace visloc::cli {

class VideoCapture {
 public:
  virtual ~VideoCapture() = default;
  // Grabs the next frame without decoding it (to take two cameras' frames close together in
  // time); Retrieve() decodes it. False at the end of a file or when the device stops.
  virtual bool Grab() = 0;
  virtual bool Retrieve(cv::Mat* image) = 0;
  // A file's frame rate and frame count; 0 when unknown.
  virtual double FileFps() const = 0;
  virtual double FileFrames() const = 0;
};

enum class CaptureKind { kDevice, kPipeline, kFile };

// The module's one exported function (C linkage, so dlsym finds it by this name): opens the
// source, or returns null with the reason in *error. `device_index` is V4L2's (kDevice only).
using OpenVideoCaptureFn = VideoCapture* (*)(CaptureKind kind, const std::string& source,
                                             int device_index, std::string* error);
constexpr const char* kOpenVideoCaptureSymbol = "visloc_open_video_capture";
constexpr const char* kVideoCaptureModule = "libvisloc_video_capture.so";

}  // namespace visloc::cli
