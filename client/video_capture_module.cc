// The video capture module (video_capture.h): OpenCV's VideoCapture behind visloc's interface,
// built as a shared module that `visloc` loads only when a command reads a camera.

#include <memory>
#include <opencv2/videoio.hpp>
#include <type_traits>

#include "client/video_capture.h"

namespace visloc::cli {
namespace {

class OpenCvCapture final : public VideoCapture {
 public:
  bool Open(CaptureKind kind, const std::string& source, int device_index) {
    switch (kind) {
      case CaptureKind::kDevice:
        return capture_.open(device_index, cv::CAP_V4L2);
      case CaptureKind::kPipeline:
        return capture_.open(source, cv::CAP_GSTREAMER);
      case CaptureKind::kFile:
        return capture_.open(source);
    }
    return false;
  }
  bool Grab() override { return capture_.grab(); }
  bool Retrieve(cv::Mat* image) override { return capture_.retrieve(*image) && !image->empty(); }
  double FileFps() const override { return capture_.get(cv::CAP_PROP_FPS); }
  double FileFrames() const override { return capture_.get(cv::CAP_PROP_FRAME_COUNT); }

 private:
  mutable cv::VideoCapture capture_;  // get() is not const in OpenCV.
};

}  // namespace
}  // namespace visloc::cli

extern "C" __attribute__((visibility("default"))) visloc::cli::VideoCapture*
visloc_open_video_capture(visloc::cli::CaptureKind kind, const std::string& source,
                          int device_index, std::string* error) {
  try {
    auto capture = std::make_unique<visloc::cli::OpenCvCapture>();
    if (capture->Open(kind, source, device_index)) return capture.release();
    *error = "cannot open it";
  } catch (const std::exception& e) {  // OpenCV throws on some backends' failures.
    *error = std::string("cannot open it: ") + e.what();
  }
  return nullptr;
}
static_assert(std::is_same_v<decltype(&visloc_open_video_capture), visloc::cli::OpenVideoCaptureFn>,
              "the module's entry point and the CLI's view of it must agree");
