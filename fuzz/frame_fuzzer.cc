// Fuzz target: what a client sends on a Localize stream and a Relocalize call, decoded and
// validated as the server does (proto/convert), then run through a fresh session.
// The first byte picks the message; the rest is its serialized protobuf.
//   0: Frame (image raw or encoded, odometry, IMU, hint) -> FromProto -> Localizer::Process
//   1: SessionStart -> camera and options -> a Localizer built from them
//   2: RelocalizeRequest -> DecodeImage against the map's camera
//   3: LocalizeResponse -> FromProto (what the client parses)
// Wire data that is wrong must end in InputError naming the problem; anything else (CheckError,
// a crash, a sanitizer report) is a bug.

#include <cstdint>
#include <memory>

#include "core/localization/localizer.h"
#include "core/map/synthetic_map.h"
#include "core/util/check.h"
#include "fuzz/fuzz_input.h"
#include "proto/convert.h"

namespace visloc::fuzz {
namespace {

const std::shared_ptr<const LocalizationMap>& SmallMap() {
  static const auto map = [] {
    SyntheticMapOptions options;
    options.keyframes = 8;
    options.points = 400;
    options.appearance_from_descriptors = true;
    return std::make_shared<const LocalizationMap>(MakeSyntheticMap(options));
  }();
  return map;
}

// A small session camera keeps each input fast; frames of any other size must be refused.
const Camera& SessionCamera() {
  static const Camera camera(64, 48, 40.0, 40.0, 31.5, 23.5);
  return camera;
}

void FuzzFrame(const std::string& bytes) {
  v1::Frame frame;
  if (!frame.ParseFromString(bytes)) return;
  const FrameInput input = proto::FromProto(frame, SessionCamera());
  Localizer localizer(SmallMap(), SessionCamera(), LocalizerOptions{});
  localizer.Process(input);
}

void FuzzSessionStart(const std::string& bytes) {
  v1::SessionStart start;
  if (!start.ParseFromString(bytes)) return;
  proto::WireLimits limits;
  limits.max_image_width = 256;  // The server allows 4096; smaller keeps the fuzzer fast.
  limits.max_image_height = 256;
  const Camera camera = proto::FromProto(start.camera(), limits);
  const LocalizerOptions options = proto::FromProto(start.options());
  Localizer localizer(SmallMap(), camera, options);
}

void FuzzRelocalizeRequest(const std::string& bytes) {
  v1::RelocalizeRequest request;
  if (!request.ParseFromString(bytes)) return;
  proto::DecodeImage(request.encoded_image(),
                     request.has_raw_image() ? &request.raw_image() : nullptr, SessionCamera());
}

void FuzzLocalizeResponse(const std::string& bytes) {
  v1::LocalizeResponse response;
  if (!response.ParseFromString(bytes)) return;
  proto::FromProto(response);
}

}  // namespace
}  // namespace visloc::fuzz

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace visloc::fuzz;
  FuzzInput input(data, size);
  const int kind = input.Byte() % 4;
  const std::string message = input.Rest();
  try {
    switch (kind) {
      case 0:
        FuzzFrame(message);
        break;
      case 1:
        FuzzSessionStart(message);
        break;
      case 2:
        FuzzRelocalizeRequest(message);
        break;
      default:
        FuzzLocalizeResponse(message);
        break;
    }
  } catch (const visloc::InputError&) {
    // Refused with a message: the intended outcome for bad wire data.
  }
  return 0;
}
