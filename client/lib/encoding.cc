// Frame encoding and the small helpers of the public header.

#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "core/image/image_codec.h"
#include "visloc/client/session.h"

namespace visloc::client {

std::string EncodeImage(const cv::Mat& image, Encoding encoding, int jpeg_quality) {
  if (image.empty()) throw std::invalid_argument("EncodeImage: empty image");
  if (image.depth() != CV_8U) throw std::invalid_argument("EncodeImage: the image is not 8-bit");
  cv::Mat grey;
  if (image.channels() == 1) {
    grey = image;
  } else if (image.channels() == 3) {
    cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
  } else if (image.channels() == 4) {
    cv::cvtColor(image, grey, cv::COLOR_BGRA2GRAY);
  } else {
    throw std::invalid_argument("EncodeImage: 1, 3 or 4 channels expected");
  }
  if (encoding == Encoding::kRaw) {
    const cv::Mat packed = grey.isContinuous() ? grey : grey.clone();
    return std::string(reinterpret_cast<const char*>(packed.data), packed.total());
  }
  std::vector<uint8_t> bytes;
  std::string error;
  const bool encoded =
      encoding == Encoding::kJpeg
          ? image::EncodeJpeg(grey, jpeg_quality, &bytes, &error)
          : image::EncodePng(grey, 1, &bytes, &error);  // Fast: a robot's CPU is weak.
  if (!encoded) throw std::invalid_argument("EncodeImage: " + error);
  return std::string(bytes.begin(), bytes.end());
}

v1::CameraModel PinholeCamera(int width, int height, double fx, double fy, double cx, double cy) {
  v1::CameraModel camera;
  camera.set_width(width);
  camera.set_height(height);
  camera.set_fx(fx);
  camera.set_fy(fy);
  camera.set_cx(cx);
  camera.set_cy(cy);
  return camera;
}

void SessionOptions::Check() const {
  if (server.empty()) throw std::invalid_argument("no server address");
  if (map_name.empty()) throw std::invalid_argument("no map name");
  if (camera.width() == 0 || camera.height() == 0)
    throw std::invalid_argument("no camera (width and height)");
  if (jpeg_quality < 1 || jpeg_quality > 100)
    throw std::invalid_argument("jpeg_quality must be 1..100");
  if (max_in_flight < 1) throw std::invalid_argument("max_in_flight must be at least 1");
  if (max_queued < 1) throw std::invalid_argument("max_queued must be at least 1");
  if (frame_deadline.count() <= 0 || stall_timeout.count() <= 0) {
    throw std::invalid_argument("frame_deadline and stall_timeout must be positive");
  }
  if (connect_timeout.count() <= 0 || backoff_initial.count() <= 0 ||
      backoff_max < backoff_initial) {
    throw std::invalid_argument(
        "connect_timeout and backoff_initial must be positive, backoff_max >= backoff_initial");
  }
  if (keepalive_time.count() < 1000 || keepalive_timeout.count() <= 0) {
    throw std::invalid_argument(
        "keepalive_time must be at least 1 s and keepalive_timeout positive");
  }
  if (credentials.tls_cert_pem.empty() != credentials.tls_key_pem.empty()) {
    throw std::invalid_argument("tls_cert_pem and tls_key_pem go together");
  }
  if (!credentials.tls_cert_pem.empty() && credentials.tls_ca_pem.empty()) {
    throw std::invalid_argument("a client certificate needs tls_ca_pem for the server's");
  }
  if (give_up_after.count() < 0) throw std::invalid_argument("give_up_after must not be negative");
  if (max_pending_events < 1) throw std::invalid_argument("max_pending_events must be at least 1");
}

const char* LinkStateName(LinkState state) {
  switch (state) {
    case LinkState::kConnecting:
      return "connecting";
    case LinkState::kConnected:
      return "connected";
    case LinkState::kDegraded:
      return "degraded";
    case LinkState::kReconnecting:
      return "reconnecting";
    case LinkState::kFailed:
      return "failed";
    case LinkState::kClosed:
      return "closed";
  }
  return "unknown";
}

const char* EventKindName(Event::Kind kind) {
  switch (kind) {
    case Event::Kind::kResult:
      return "result";
    case Event::Kind::kLate:
      return "late";
    case Event::Kind::kDropped:
      return "dropped";
    case Event::Kind::kUndelivered:
      return "undelivered";
    case Event::Kind::kLinkState:
      return "link";
  }
  return "unknown";
}

}  // namespace visloc::client
