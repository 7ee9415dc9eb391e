#pragma once
// A camera the CLI reads through OpenCV's VideoCapture: a V4L2 device ("/dev/video0" or "0"), a
// GStreamer pipeline (anything with a "!"), or a video file. `visloc stream --camera` and
// `visloc map build --server --camera L --camera R` read their cameras through it.

#include <string>

#include <opencv2/core.hpp>
#include <opencv2/videoio.hpp>

namespace visloc::cli {

class VideoSource {
 public:
  // Throws InputError naming `flag` and the source when it cannot be opened.
  VideoSource(const std::string& source, const std::string& flag);

  // A device or a pipeline (frames come at the camera's pace), not a file.
  bool live() const { return live_; }
  // A file's frame rate and frame count (0 when unknown or live).
  double file_fps() const { return file_fps_; }
  size_t file_frames() const;
  // Grabs the next frame without decoding it (for pairing two cameras' frames in time), then
  // Retrieve() decodes it; Read() is both. False at the end.
  bool Grab() { return capture_.grab(); }
  bool Retrieve(cv::Mat* image) { return capture_.retrieve(*image) && !image->empty(); }
  bool Read(cv::Mat* image) { return capture_.read(*image) && !image->empty(); }

 private:
  mutable cv::VideoCapture capture_;
  bool live_ = false;
  double file_fps_ = 0.0;
};

}  // namespace visloc::cli
