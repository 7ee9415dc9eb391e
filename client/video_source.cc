#include "client/video_source.h"

#include <dlfcn.h>
#include <unistd.h>

#include <filesystem>
#include <mutex>
#include <thread>

#include "core/util/check.h"

namespace visloc::cli {
namespace {

// Where the module is looked for: beside the binary (the build tree), then where `cmake
// --install` puts it relative to the binary (VISLOC_CAPTURE_MODULE_DIR, from bin/).
std::vector<std::string> ModuleCandidates() {
  char exe[4096];
  const ssize_t n = readlink("/proc/self/exe", exe, sizeof(exe) - 1);
  const std::filesystem::path dir =
      n > 0 ? std::filesystem::path(std::string(exe, static_cast<size_t>(n))).parent_path()
            : std::filesystem::path(".");
  return {(dir / kVideoCaptureModule).string(),
          (dir / VISLOC_CAPTURE_MODULE_DIR / kVideoCaptureModule).lexically_normal().string()};
}

// The module's entry point, loaded once (never unloaded: its objects may outlive any caller).
OpenVideoCaptureFn LoadModule() {
  static std::once_flag once;
  static OpenVideoCaptureFn open = nullptr;
  static std::string why_not;
  std::call_once(once, [] {
    for (const std::string& path : ModuleCandidates()) {
      void* module = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
      if (!module) {
        why_not += (why_not.empty() ? "" : "; ") + std::string(dlerror());
        continue;
      }
      open = reinterpret_cast<OpenVideoCaptureFn>(dlsym(module, kOpenVideoCaptureSymbol));
      if (open) return;
      why_not += (why_not.empty() ? "" : "; ") + path + ": no " + kOpenVideoCaptureSymbol;
    }
  });
  if (!open) {
    throw InputError(
        "cameras and video files are read by visloc's video capture module, which "
        "is not installed here (" +
        why_not + ")");
  }
  return open;
}

}  // namespace

VideoSource::VideoSource(const std::string& source, const std::string& flag) {
  const bool device =
      source.rfind("/dev/video", 0) == 0 ||
      (!source.empty() && source.find_first_not_of("0123456789") == std::string::npos);
  live_ = device || source.find('!') != std::string::npos;
  // A missing file is named here: OpenCV would probe every backend for it first.
  if (!live_ && !std::filesystem::is_regular_file(source)) {
    throw InputError(flag + " " + source + ": no such video file (nor a device or pipeline)");
  }
  const CaptureKind kind = device  ? CaptureKind::kDevice
                           : live_ ? CaptureKind::kPipeline
                                   : CaptureKind::kFile;
  const int index = !device                              ? -1
                    : source.rfind("/dev/video", 0) == 0 ? std::stoi(source.substr(10))
                                                         : std::stoi(source);
  std::string why;
  try {
    capture_.reset(LoadModule()(kind, source, index, &why));
  } catch (const InputError& e) {
    throw InputError(flag + " " + source + ": " + e.what());
  }
  if (!capture_) throw InputError(flag + " " + source + ": " + why);
  file_fps_ = live_ ? 0.0 : capture_->FileFps();
}

size_t VideoSource::file_frames() const {
  const double frames = live_ ? 0.0 : capture_->FileFrames();
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
