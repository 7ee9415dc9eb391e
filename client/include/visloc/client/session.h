#pragma once
// visloc::client — the robot's side of a localization session, as a library a robot program
// links (find_package(visloc CONFIG), target visloc::client). It depends on the generated
// visloc.v1 messages, gRPC and OpenCV's core and image codecs only: no mapper, no engine.
//
//   visloc::client::SessionOptions options;
//   options.server = "10.0.0.5:50051";
//   options.map_name = "lab";
//   options.camera = visloc::client::CameraFromYaml("calib/cam0/sensor.yaml");
//   auto session = visloc::client::Session::Open(options);
//   session->Submit(frame);                      // every camera frame; never blocks
//   while (auto event = session->Next(50ms)) {}  // answers, drops and link changes
//
// What the library does about the link (WiFi that stalls, access points that go away):
// - at most `max_in_flight` frames are on the wire; frames the link cannot take yet wait in a
//   queue of `max_queued`, and the oldest waiting frame is dropped when a newer one arrives or
//   when it has waited longer than `frame_deadline` (a kDropped event, never silent); its gyro
//   samples go with the next frame sent, so the server's rotation covers the whole gap;
// - an answer arriving later than `frame_deadline` after its frame was submitted is reported
//   kLate, not as a pose to steer on;
// - gRPC keepalive pings find dead connections; no answer for `stall_timeout` while frames are
//   on the wire ends the stream as stalled;
// - a broken or stalled stream is reopened on a fresh connection with exponential backoff, and
//   the session resumes: the first frame after it carries the last good pose as
//   map_from_cam_hint (moved by the robot's odometry in between, when frames carry odometry), so
//   the server tracks from it instead of relocalizing globally. Frames on the wire when the
//   stream broke are reported kUndelivered;
// - link state changes (connected, degraded, reconnecting, failed) are events.
//
// Poses follow the service's conventions (product.md): map_from_cam, OpenCV camera frame,
// metres, Hamilton quaternions; times are nanoseconds.

#include <chrono>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "visloc/v1/visloc.pb.h"

namespace visloc::client {

namespace v1 = ::visloc::v1;

// How frames travel. JPEG is the robot's usual choice on WiFi (about 10x smaller than PNG for a
// small loss of accuracy: docs/robot-link.md has the figures).
enum class Encoding { kJpeg, kPng, kRaw };

struct Credentials {
  std::string token;         // Bearer token; empty: none.
  std::string tls_ca_pem;    // Trust for the server's certificate; empty: plaintext.
  std::string tls_cert_pem;  // Mutual TLS: this client's certificate chain and key.
  std::string tls_key_pem;
  std::string tls_target_name;  // Overrides the name checked against the certificate.
};

enum class LinkState {
  kConnecting,    // Opening the first stream.
  kConnected,     // A stream is open and answering.
  kDegraded,      // Open, but the oldest frame on the wire is unanswered past frame_deadline.
  kReconnecting,  // The stream broke or stalled; reopening with backoff.
  kFailed,        // The server refused the session for good (unknown map, bad camera, auth).
  kClosed,        // Close() was called.
};
const char* LinkStateName(LinkState state);

struct Event {
  enum class Kind {
    kResult,       // The server's answer to a frame (`response`).
    kLate,         // An answer that came after frame_deadline (`response`): do not steer on it.
    kDropped,      // A frame never sent: the link was slower than the camera (`detail` says).
    kUndelivered,  // A frame sent on a stream that broke before it was answered.
    kLinkState,    // The link changed state (`link_state`, `detail`).
  };
  Kind kind = Kind::kResult;
  int64_t timestamp_ns = 0;  // The frame's (not for kLinkState).
  double latency_ms = 0.0;   // Submit to answer (kResult, kLate).
  v1::LocalizeResponse response;
  LinkState link_state = LinkState::kConnecting;
  std::string detail;
};
const char* EventKindName(Event::Kind kind);

struct SessionOptions {
  std::string server;  // gRPC target: HOST:PORT, dns:///HOST:PORT, ipv4:A:P,B:P.
  Credentials credentials;
  std::string map_name;
  v1::CameraModel camera;      // The camera the frames come from (PinholeCamera() helps).
  // A rig: the robot's other cameras, each with its pose on the body (the frame of
  // session.body_from_cam, or `camera`'s own when that is unset). Every Frame then carries one
  // image of each in rig_images. RigCameraFromYaml reads one from its sensor.yaml.
  std::vector<v1::RigCamera> rig_cameras;
  v1::SessionOptions session;  // The engine's options (drop policy, camera height, ...).
  std::string robot_id;        // For the server's logs.

  Encoding encoding = Encoding::kJpeg;
  int jpeg_quality = 90;  // 1..100.

  int max_in_flight = 2;  // Frames sent and not yet answered.
  int max_queued = 2;     // Frames waiting for the link; the oldest is dropped beyond this.
  // Replays (every frame matters, none is live): Submit() waits for room in the queue instead
  // of dropping the oldest frame. A live camera leaves this off.
  bool wait_for_room = false;
  std::chrono::milliseconds frame_deadline{1000};  // Older frames are dropped, older answers late.
  std::chrono::milliseconds stall_timeout{2000};   // No answer this long: the stream is stalled.

  // Reconnection: the first retry after `backoff_initial`, doubling up to `backoff_max`.
  std::chrono::milliseconds connect_timeout{1000};
  std::chrono::milliseconds backoff_initial{50};
  std::chrono::milliseconds backoff_max{500};
  bool resume_with_hint = true;
  // When no stream could be opened for this long, the session fails (kFailed). 0: never give
  // up (a robot keeps trying; a one-off command should not).
  std::chrono::milliseconds give_up_after{0};

  // gRPC keepalive. Not below the server's --keepalive-min-ping-interval-s (default 5), which
  // would strike this client off (gRPC's keepalive guidance).
  std::chrono::milliseconds keepalive_time{10000};
  std::chrono::milliseconds keepalive_timeout{5000};

  // When set, events are delivered here (from the library's threads: return quickly) instead
  // of through Next().
  std::function<void(const Event&)> on_event;
  int max_pending_events = 4096;  // Next()'s queue; the oldest events go beyond this.

  // Throws std::invalid_argument saying what is wrong with the first bad value.
  void Check() const;
};

// One image of a rig's other camera (SessionOptions::rig_cameras), taken with the frame.
struct RigFrameImage {
  int64_t timestamp_ns = 0;
  cv::Mat image;        // 8-bit grey or BGR, that camera's size; empty: it gave none this time.
  std::string encoded;  // Or already encoded PNG/JPEG bytes.
};

struct Frame {
  int64_t timestamp_ns = 0;
  cv::Mat image;  // 8-bit grey or BGR (converted to grey), the camera's size.
  std::optional<v1::Pose> odom_from_cam;      // Odometry (only its motion is used).
  std::vector<v1::ImuSample> imu;             // Samples since the previous frame (a dropped
                                              // frame's go with the next one sent).
  std::optional<v1::Pose> map_from_cam_hint;  // An external guess.
  // Already encoded PNG/JPEG bytes (sent as they are; `image` is then ignored).
  std::string encoded;
  std::vector<RigFrameImage> rig_images;  // One per rig camera, in SessionOptions' order.
};

struct SessionStats {
  uint64_t submitted = 0;
  uint64_t sent = 0;
  uint64_t answered = 0;  // kResult.
  uint64_t late = 0;
  uint64_t dropped = 0;
  uint64_t undelivered = 0;
  uint64_t streams_opened = 0;  // 1 + successful reconnections.
  uint64_t bytes_sent = 0;      // Encoded image bytes.
};

class Session {
 public:
  // Starts connecting in the background and returns at once. Throws std::invalid_argument for
  // options that fail Check().
  static std::unique_ptr<Session> Open(const SessionOptions& options);
  virtual ~Session() = default;

  // Hands a frame to the library; never blocks on the network (unless wait_for_room). Returns
  // false, with a reason, for a frame that cannot be sent (wrong size, empty, after Close(), or
  // after the server refused the session: link_state() kFailed).
  virtual bool Submit(const Frame& frame, std::string* why_not = nullptr) = 0;

  // The next event, waiting up to `wait`; nothing when none came (or on_event is set).
  virtual std::optional<Event> Next(std::chrono::milliseconds wait) = 0;

  // Stops taking frames, waits up to `drain` for the answers to frames already sent or queued,
  // then ends the stream. Idempotent; the destructor calls it with no wait.
  virtual void Close(std::chrono::milliseconds drain = std::chrono::milliseconds(2000)) = 0;

  virtual LinkState link_state() const = 0;
  virtual SessionStats stats() const = 0;
};

// One image, no session: the Relocalize RPC, with the options' server, credentials, map, camera
// and encoding. The answer says whether it was localized and with what evidence. Throws
// std::runtime_error with the server's reason when the call fails (unknown map, unreachable
// server within `timeout`).
v1::RelocalizeResponse Relocalize(const SessionOptions& options, const Frame& frame,
                                  std::chrono::milliseconds timeout);

// A pinhole camera without distortion (add four distortion values for radial-tangential, or
// set lens_model EQUIDISTANT with k1..k4).
v1::CameraModel PinholeCamera(int width, int height, double fx, double fy, double cx, double cy);

// The camera a calibration's sensor.yaml describes (the EuRoC/Kalibr layout that `visloc
// calibrate` and `visloc sim` write): resolution, pinhole intrinsics [fu, fv, cu, cv] and the
// lens (distortion_model radial-tangential, equidistant or none, with its four coefficients).
// Throws std::invalid_argument naming the file and what is wrong with it.
v1::CameraModel CameraFromYaml(const std::string& path);
// A rig's camera from its sensor.yaml: CameraFromYaml's camera, placed on the body by the
// file's T_BS (body_from_sensor, row-major 4x4), with `name` for reports. Throws
// std::invalid_argument as CameraFromYaml does, and for a T_BS that is not a rigid transform.
v1::RigCamera RigCameraFromYaml(const std::string& path, const std::string& name);

// The largest answer a client accepts (gRPC's default is 4 MiB): a map download chunk or a
// relocalization's candidate list stay far below it. The wire's limit, defined once in
// visloc.proto (WireLimit), which the server and the Python package use too.
constexpr int kMaxReceiveMessageBytes = v1::MAX_MESSAGE_BYTES;

// The frame's image as it would go on the wire: grey, then encoded. Throws
// std::invalid_argument for an empty image or one the encoder refuses.
std::string EncodeImage(const cv::Mat& image, Encoding encoding, int jpeg_quality);

}  // namespace visloc::client
