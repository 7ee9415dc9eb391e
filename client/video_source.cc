#include "client/video_source.h"

#include <filesystem>
#include <thread>

#include "core/util/check.h"

namespace visloc::cli {

VideoSource::VideoSource(const std::string& source, const std::string& flag) {
  const bool device =
      source.rfind("/dev/video", 0) == 0 ||
      (!source.empty() && source.find_first_not_of("0123456789") == std::string::npos);
  live_ = device || source.find('!') != std::string::npos;
  if (device) {
    const int index =
        source.rfind("/dev/video", 0) == 0 ? std::stoi(source.substr(10)) : std::stoi(source);
    capture_.open(index, cv::CAP_V4L2);
  } else if (source.find('!') != std::string::npos) {
    capture_.open(source, cv::CAP_GSTREAMER);
  } else {
    // A missing file is named here: OpenCV would probe every backend for it first.
    if (!std::filesystem::is_regular_file(source)) {
      throw InputError(flag + " " + source + ": no such video file (nor a device or pipeline)");
    }
    capture_.open(source);
  }
  if (!capture_.isOpened()) throw InputError(flag + " " + source + ": cannot open it");
  file_fps_ = live_ ? 0.0 : capture_.get(cv::CAP_PROP_FPS);
}

size_t VideoSource::file_frames() const {
  const double frames = live_ ? 0.0 : capture_.get(cv::CAP_PROP_FRAME_COUNT);
  return frames > 0 ? static_cast<size_t>(frames) : 0;
}

int64_t VideoSource::Stamp(size_t index, double rate_hz, bool pace,
                           std::chrono::steady_clock::time_point start) const {
  if (live_ || rate_hz <= 0) {  // Stamped when read.
    return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now() -
                                                                start)
               .count() +
           1;  // Strictly positive and increasing.
  }
  const auto due = std::chrono::nanoseconds(static_cast<int64_t>(index * 1e9 / rate_hz));
  if (pace) std::this_thread::sleep_until(start + due);
  return due.count() + 1;
}

}  // namespace visloc::cli
