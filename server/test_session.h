#pragma once
// For the server's tests (and the client library's, which talk to a real service): a small
// synthetic map "lab" in a maps folder, and the requests of a session on it with a blank camera
// image (the engine runs, nothing of the map is in view).

#include <string>

#include "core/camera/camera.h"
#include "core/map/synthetic_map.h"
#include "mapstore/map_store.h"
#include "proto/geometry_convert.h"
#include "visloc/v1/visloc.pb.h"

namespace visloc::server::testing {

// Writes the map "lab" (6 keyframes, 300 points) as DIR/lab.db.
inline void WriteLabMap(const std::string& maps_dir) {
  SyntheticMapOptions options;
  options.keyframes = 6;
  options.points = 300;
  options.name = "lab";
  mapstore::SaveMap(MakeSyntheticMap(options), maps_dir + "/lab.db",
                    mapstore::SaveMapOptions{4096});
}

// The camera the sessions below declare.
inline Camera TestCamera() { return Camera(160, 120, 80.0, 80.0, 79.5, 59.5); }

inline v1::LocalizeRequest StartRequest(v1::FrameDropPolicy policy = v1::PROCESS_ALL,
                                        const std::string& robot_id = "") {
  v1::LocalizeRequest start;
  start.mutable_start()->set_map_name("lab");
  start.mutable_start()->set_robot_id(robot_id);
  start.mutable_start()->mutable_options()->set_drop_policy(policy);
  proto::ToProto(TestCamera(), start.mutable_start()->mutable_camera());
  return start;
}

// Frame `i` (15 Hz stamps): a uniform grey raw image of the test camera's size.
inline v1::LocalizeRequest FrameRequest(int i) {
  const Camera camera = TestCamera();
  v1::LocalizeRequest frame;
  frame.mutable_frame()->set_timestamp_ns((i + 1) * 66'666'667LL);
  v1::RawImage* raw = frame.mutable_frame()->mutable_raw();
  raw->set_width(camera.width());
  raw->set_height(camera.height());
  raw->set_pixels(std::string(camera.width() * camera.height(), '\x60'));
  return frame;
}

}  // namespace visloc::server::testing
