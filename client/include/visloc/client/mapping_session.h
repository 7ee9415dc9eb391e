#pragma once
// visloc::client::MappingSession — a robot streams a stereo run to the server, which builds the
// map as frames arrive and publishes it when the run ends (the Mapping service). The same
// library as the localization Session (find_package(visloc CONFIG), target visloc::client).
//
//   visloc::client::MappingSessionOptions options;
//   options.server = "10.0.0.5:50051";
//   options.credentials.token = admin_token;   // mapping is for admins
//   options.map_name = "hall";
//   options.rig = ...;                         // both cameras and their T_BS
//   auto mapping = visloc::client::MappingSession::Open(options);
//   for (each stereo frame) mapping->Submit(frame);  // blocks while max_in_flight are unanswered
//   for (const auto& a : mapping->TakeAnswers()) ...  // tracking, keyframes, points per frame
//   v1::MappingProgress published = mapping->Finish();  // the map, or an exception saying why
//
// What it does about the link: at most `max_in_flight` frames are unanswered (Submit waits for
// room: a map needs every frame, so a live driver that cannot wait decides what to skip). When
// the stream breaks, the session reconnects with backoff and resumes the same job: the server
// keeps it for its --mapping-resume-s window and answers with the last frame it mapped; the
// frames after it that were lost on the way are sent again from the session's buffer of
// unanswered frames. A link down longer than `resume_timeout` fails the session: nothing is
// published.

#include <chrono>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "visloc/client/session.h"
#include "visloc/v1/visloc.pb.h"

namespace visloc::client {

struct MappingSessionOptions {
  std::string server;  // gRPC target: HOST:PORT.
  Credentials credentials;
  std::string map_name;
  v1::StereoRig rig;           // Both cameras and each one's pose on the body.
  v1::MappingOptions mapping;  // Replace, features, keyframe thresholds, ... (zeros: defaults).
  std::string robot_id;        // For the server's logs and job list.
  // Lossless by default: a map from JPEG frames differs slightly from the recording's own.
  Encoding encoding = Encoding::kPng;
  int jpeg_quality = 95;
  int max_in_flight = 8;                            // Frames sent and not yet answered.
  std::chrono::milliseconds resume_timeout{30000};  // A link down this long fails the session.
  std::chrono::milliseconds backoff_initial{250};
  std::chrono::milliseconds backoff_max{2000};
  // Throws std::invalid_argument saying what is wrong with the first bad value.
  void Check() const;
};

struct StereoFrame {
  int64_t timestamp_ns = 0;  // Increasing.
  cv::Mat left, right;       // 8-bit grey or BGR, each its camera's size.
  // Already encoded PNG/JPEG bytes, sent as they are (the images are then ignored).
  std::string left_encoded, right_encoded;
  std::vector<v1::ImuSample> imu;
  std::optional<v1::Pose> odom_from_cam;
};

// The server's answer to a frame, and how long it took from Submit.
struct MappingAnswer {
  v1::MappingProgress progress;
  double latency_ms = 0.0;
};

struct MappingSessionStats {
  uint64_t submitted = 0;
  uint64_t answered = 0;
  uint64_t lost = 0;          // Frames the mapper could not track.
  uint64_t frame_errors = 0;  // Frames the server refused (the answer says why).
  uint64_t resumes = 0;       // Times the job was taken up again after the link broke.
  uint64_t bytes_sent = 0;    // Encoded image bytes.
};

class MappingSession {
 public:
  // Connects and starts the job. Throws std::invalid_argument for bad options and
  // std::runtime_error with the server's reason when it refuses the job (name taken, not an
  // admin, mapping off, a bad rig) or cannot be reached.
  static std::unique_ptr<MappingSession> Open(const MappingSessionOptions& options);
  virtual ~MappingSession() = default;

  // Sends a frame, waiting while max_in_flight frames are unanswered and while the link is
  // being resumed. Returns false, with a reason, when the job cannot go on (the link stayed
  // down past resume_timeout, or the server failed the job): nothing will be published.
  virtual bool Submit(const StereoFrame& frame, std::string* why_not = nullptr) = 0;
  // The answers that arrived since the last call, oldest first.
  virtual std::vector<MappingAnswer> TakeAnswers() = 0;
  // Ends the run (MappingEnd) and waits for the outcome: the PUBLISHED answer (the map's
  // MapInfo). Throws std::runtime_error saying why nothing was published.
  virtual v1::MappingProgress Finish() = 0;
  virtual uint64_t job_id() const = 0;
  virtual MappingSessionStats stats() const = 0;
};

}  // namespace visloc::client
