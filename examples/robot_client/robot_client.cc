// A minimal robot program on visloc's client library: streams a folder of images (a camera's
// frames, named by their timestamps in nanoseconds, as in EuRoC's cam0/data) to visloc-server at
// 15 Hz and prints each pose. A real robot hands its camera driver's frames to Submit() instead.
//
//   robot_client SERVER MAP IMAGE_DIR --camera-yaml SENSOR_YAML   the camera of a calibration
//   robot_client SERVER MAP IMAGE_DIR WIDTH HEIGHT FX FY CX CY     an undistorted pinhole camera
//
// SENSOR_YAML is the camera's sensor.yaml as `visloc calibrate` writes it (or EuRoC's cam0).

#include <visloc/client/session.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace {

const char kUsage[] =
    "usage: robot_client SERVER MAP IMAGE_DIR --camera-yaml SENSOR_YAML\n"
    "       robot_client SERVER MAP IMAGE_DIR WIDTH HEIGHT FX FY CX CY\n";

// The camera from the arguments after IMAGE_DIR; throws std::invalid_argument.
visloc::v1::CameraModel CameraFromArguments(int argc, char** argv) {
  if (argc == 6 && std::string(argv[4]) == "--camera-yaml") {
    return visloc::client::CameraFromYaml(argv[5]);
  }
  if (argc == 10) {
    return visloc::client::PinholeCamera(std::stoi(argv[4]), std::stoi(argv[5]),
                                         std::stod(argv[6]), std::stod(argv[7]),
                                         std::stod(argv[8]), std::stod(argv[9]));
  }
  throw std::invalid_argument("wrong arguments");
}

}  // namespace

int main(int argc, char** argv) {
  visloc::client::SessionOptions options;
  try {
    if (argc < 4) throw std::invalid_argument("wrong arguments");
    options.camera = CameraFromArguments(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "robot_client: %s\n%s", e.what(), kUsage);
    return 2;
  }
  options.server = argv[1];
  options.map_name = argv[2];
  options.robot_id = "example-robot";
  options.encoding = visloc::client::Encoding::kJpeg;
  options.jpeg_quality = 90;
  // Every frame ends as exactly one of: answered, late, dropped (a live robot's queue keeps the
  // newest frames when the link or the server is slower than the camera) or undelivered.
  int posed = 0, answered = 0, late = 0, dropped = 0, undelivered = 0;
  options.on_event = [&](const visloc::client::Event& event) {
    using Kind = visloc::client::Event::Kind;
    if (event.kind == Kind::kLate) ++late;
    if (event.kind == Kind::kDropped) ++dropped;
    if (event.kind == Kind::kUndelivered) ++undelivered;
    if (event.kind == Kind::kLinkState) {
      std::printf("link %s: %s\n", visloc::client::LinkStateName(event.link_state),
                  event.detail.c_str());
    } else if (event.kind == Kind::kResult) {
      ++answered;
      const visloc::v1::Pose& p = event.response.map_from_cam();
      if (event.response.has_pose()) ++posed;
      std::printf("%.3f %s position %.3f %.3f %.3f inliers %u latency %.1f ms\n",
                  event.timestamp_ns * 1e-9,
                  visloc::v1::Status_Name(event.response.status()).c_str(), p.tx(), p.ty(),
                  p.tz(), event.response.stats().inliers(), event.latency_ms);
    }
  };
  std::vector<std::filesystem::path> images;
  for (const auto& entry : std::filesystem::directory_iterator(argv[3])) {
    images.push_back(entry.path());
  }
  std::sort(images.begin(), images.end());
  auto session = visloc::client::Session::Open(options);
  for (const auto& path : images) {
    visloc::client::Frame frame;
    frame.timestamp_ns = std::stoll(path.stem().string());
    // The file's PNG bytes go as they are, as a camera that compresses on board would send
    // them: the robot decodes nothing (frame.image takes a cv::Mat instead).
    std::ifstream file(path, std::ios::binary);
    frame.encoded.assign(std::istreambuf_iterator<char>(file), std::istreambuf_iterator<char>());
    std::string why_not;
    if (!session->Submit(frame, &why_not)) std::fprintf(stderr, "not sent: %s\n", why_not.c_str());
    std::this_thread::sleep_for(std::chrono::milliseconds(66));
  }
  session->Close();
  std::printf("answered %d of %zu frames, %d with a pose; %d late, %d dropped, %d undelivered\n",
              answered, images.size(), posed, late, dropped, undelivered);
  return answered > 0 ? 0 : 1;
}
