#pragma once
// A camera the CLI reads: a V4L2 device ("/dev/video0" or "0"), a GStreamer pipeline (anything
// with a "!"), or a video file, through the video capture module (video_capture.h: OpenCV's
// VideoCapture, loaded when the first source is opened). `visloc stream --camera` and
// `visloc map build --server --camera L --camera R` read their cameras through it.

#include <chrono>
#include <memory>
#include <string>

#include <opencv2/core.hpp>

#include "client/video_capture.h"

namespace visloc::cli {

class VideoSource {
 public:
  // Throws InputError naming `flag` and the source when it cannot be opened, or when the video
  // capture module is not installed.
  VideoSource(const std::string& source, const std::string& flag);

  // A device or a pipeline (frames come at the camera's pace), not a file.
  bool live() const { return live_; }
  // A file's frame rate and frame count (0 when unknown or live).
  double file_fps() const { return file_fps_; }
  size_t file_frames() const;
  // Grabs the next frame without decoding it (for pairing two cameras' frames in time), then
  // Retrieve() decodes it. False at the end.
  bool Grab() { return capture_->Grab(); }
  bool Retrieve(cv::Mat* image) { return capture_->Retrieve(image); }
  // The stamp of the `index`-th frame read since `start` (ns, strictly positive): the clock for a
  // live source or an unknown rate, else its position in the file at `rate_hz`. With `pace`, a
  // file's frame is first waited for until it is due at that rate.
  int64_t Stamp(size_t index, double rate_hz, bool pace,
                std::chrono::steady_clock::time_point start) const;

 private:
  std::unique_ptr<VideoCapture> capture_;
  bool live_ = false;
  double file_fps_ = 0.0;
};

}  // namespace visloc::cli
