// The client library against the real localization service on a loopback port (the service
// in-process, so a test can slow its engine down). Link faults through a proxy are end-to-end
// tests (tests/robot_link_e2e_test.cc).

#include "visloc/client/session.h"

#include <gmock/gmock.h>
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <map>
#include <mutex>
#include <thread>

#include "client/lib/channel.h"
#include "core/util/temp_dir.h"
#include "server/localization_service.h"
#include "server/test_session.h"

namespace visloc::client {
namespace {

using ::testing::HasSubstr;

class ClientSessionTest : public ::testing::Test {
 protected:
  void SetUp() override {
    server::testing::WriteLabMap(maps_dir_.path());
    maps_ = std::make_unique<server::MapCache>(maps_dir_.path(), std::chrono::seconds(60));
    service_ =
        std::make_unique<server::LocalizationService>(maps_.get(), server::ServiceLimits{}, &auth_);
    // A slow engine on demand (set before serving; tests change only the atomic delay).
    service_->SetBeforeFrameHookForTesting([this](const v1::Frame& frame) {
      {
        std::lock_guard<std::mutex> lock(engine_mutex_);
        engine_starts_.emplace_back(frame.timestamp_ns(), std::chrono::steady_clock::now());
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(engine_delay_ms_.load()));
      std::lock_guard<std::mutex> lock(engine_mutex_);
      for (const v1::ImuSample& s : frame.imu()) engine_imu_ns_.push_back(s.timestamp_ns());
    });
    grpc::ServerBuilder builder;
    builder.AddListeningPort("127.0.0.1:0", grpc::InsecureServerCredentials(), &port_);
    builder.RegisterService(service_.get());
    server_ = builder.BuildAndStart();
    ASSERT_GT(port_, 0);
  }
  void TearDown() override { server_->Shutdown(); }

  SessionOptions Options(const std::string& map = "lab") const {
    SessionOptions o;
    o.server = "127.0.0.1:" + std::to_string(port_);
    o.map_name = map;
    o.camera = PinholeCamera(160, 120, 80, 80, 79.5, 59.5);
    return o;
  }
  static Frame MakeFrame(int i) {
    Frame frame;
    frame.timestamp_ns = (i + 1) * 66'666'667LL;
    frame.image = cv::Mat(120, 160, CV_8UC1);
    cv::randu(frame.image, 0, 255);
    return frame;
  }
  // Events until `done` says stop or `seconds` pass.
  static std::vector<Event> Collect(Session* session, double seconds,
                                    const std::function<bool(const std::vector<Event>&)>& done) {
    std::vector<Event> events;
    const auto until = std::chrono::steady_clock::now() +
                       std::chrono::milliseconds(static_cast<int>(seconds * 1000));
    while (std::chrono::steady_clock::now() < until && !done(events)) {
      if (auto e = session->Next(std::chrono::milliseconds(20))) events.push_back(*e);
    }
    return events;
  }
  static int Count(const std::vector<Event>& events, Event::Kind kind) {
    return static_cast<int>(std::count_if(events.begin(), events.end(),
                                          [kind](const Event& e) { return e.kind == kind; }));
  }

  TempDir maps_dir_{"visloc-client-test"};
  const server::TokenAuth auth_;
  std::unique_ptr<server::MapCache> maps_;
  std::unique_ptr<server::LocalizationService> service_;
  std::unique_ptr<grpc::Server> server_;
  int port_ = 0;
  std::atomic<int> engine_delay_ms_{0};
  std::mutex engine_mutex_;
  std::vector<int64_t> engine_imu_ns_;  // The gyro sample stamps the engine got, in order.
  // Each frame the engine took (its stamp) and when, in order.
  std::vector<std::pair<int64_t, std::chrono::steady_clock::time_point>> engine_starts_;
};

// A refused session's next stream starts at the next replica of a list.
TEST(ReplicaListTest, TheNextReplicaComesFirst) {
  EXPECT_EQ(NextReplicaFirst("ipv4:10.0.0.5:50051,10.0.0.6:50051,10.0.0.7:50051"),
            "ipv4:10.0.0.6:50051,10.0.0.7:50051,10.0.0.5:50051");
  EXPECT_EQ(NextReplicaFirst("ipv6:[::1]:5001,[::1]:5002"), "ipv6:[::1]:5002,[::1]:5001");
  for (const char* one : {"ipv4:10.0.0.5:50051", "localhost:50051", "dns:///fleet:50051"}) {
    EXPECT_EQ(NextReplicaFirst(one), one);
  }
}

// A replica at capacity: refuses every session before reading a frame, as admission control
// does (server/admission.h), and counts the sessions that reached it.
class FullReplica final : public v1::Localization::Service {
 public:
  grpc::Status Localize(
      grpc::ServerContext*,
      grpc::ServerReaderWriter<v1::LocalizeResponse, v1::LocalizeRequest>*) override {
    ++sessions;
    return {grpc::StatusCode::RESOURCE_EXHAUSTED, "server at capacity (a test replica)"};
  }
  std::atomic<int> sessions{0};
};

// Two replicas, the first in the robot's list full. A robot asks the replicas in its list's
// order: the full one once, then the other at once, never the full one twice in a row (a CI
// run's robot was sent back to the full replica by the channel's balancer, refused twice,
// backed off a second and never served). A list with the free replica first never touches
// the full one.
TEST_F(ClientSessionTest, ARobotAsksItsReplicasInTheListsOrder) {
  FullReplica full;
  int full_port = 0;
  grpc::ServerBuilder builder;
  builder.AddListeningPort("127.0.0.1:0", grpc::InsecureServerCredentials(), &full_port);
  builder.RegisterService(&full);
  const std::unique_ptr<grpc::Server> full_server = builder.BuildAndStart();
  ASSERT_GT(full_port, 0);
  const std::string full_address = "127.0.0.1:" + std::to_string(full_port);
  const std::string free_address = "127.0.0.1:" + std::to_string(port_);
  constexpr int kRobots = 12;
  for (const bool full_first : {true, false}) {
    full.sessions = 0;
    for (int robot = 0; robot < kRobots; ++robot) {
      SessionOptions options = Options();
      options.server = full_first ? "ipv4:" + full_address + "," + free_address
                                  : "ipv4:" + free_address + "," + full_address;
      // A camera at 20 Hz until the first answer: frames sent to the full replica before its
      // refusal came back are not answered, later ones are.
      auto session = Session::Open(options);
      std::vector<Event> events;
      for (int i = 0; i < 200 && Count(events, Event::Kind::kResult) == 0; ++i) {
        ASSERT_TRUE(session->Submit(MakeFrame(i)));
        const std::vector<Event> more =
            Collect(session.get(), 0.05, [](const auto&) { return false; });
        events.insert(events.end(), more.begin(), more.end());
      }
      session->Close();
      ASSERT_GE(Count(events, Event::Kind::kResult), 1) << "robot " << robot;
    }
    EXPECT_EQ(full.sessions.load(), full_first ? kRobots : 0)
        << "full replica first: " << full_first;
  }
  full_server->Shutdown();
}

TEST_F(ClientSessionTest, EveryFrameIsAnsweredInOrderForEachEncoding) {
  for (const Encoding encoding : {Encoding::kJpeg, Encoding::kPng, Encoding::kRaw}) {
    SessionOptions options = Options();
    options.encoding = encoding;
    options.wait_for_room = true;
    auto session = Session::Open(options);
    for (int i = 0; i < 8; ++i) ASSERT_TRUE(session->Submit(MakeFrame(i)));
    const std::vector<Event> events = Collect(
        session.get(), 20, [](const auto& e) { return Count(e, Event::Kind::kResult) == 8; });
    session->Close();
    std::vector<int64_t> answered;
    for (const Event& e : events) {
      if (e.kind != Event::Kind::kResult) continue;
      EXPECT_NE(e.response.status(), v1::STATUS_ERROR) << e.response.error();
      EXPECT_GT(e.latency_ms, 0.0);
      answered.push_back(e.timestamp_ns);
    }
    ASSERT_EQ(answered.size(), 8u) << static_cast<int>(encoding);
    for (int i = 0; i < 8; ++i) EXPECT_EQ(answered[i], MakeFrame(i).timestamp_ns);
    const SessionStats stats = session->stats();
    EXPECT_EQ(stats.sent, 8u);
    EXPECT_EQ(stats.dropped, 0u);
    EXPECT_EQ(stats.streams_opened, 1u);
    EXPECT_EQ(session->link_state(), LinkState::kClosed);
  }
}

// The server takes 100 ms a frame and the camera gives one every 10 ms: the library keeps two
// frames on the wire and two waiting, drops the oldest waiting ones (reported, never silent),
// and the answers that come stay fresh instead of falling further and further behind. The
// frame deadline is set far out, so that only the queue bound keeps them fresh. Fresh is
// counted, not timed: between a frame's Submit and the engine taking it, the engine takes at
// most the frames on the wire and waiting ahead of it (four), however slow a loaded machine
// makes each one. Without dropping, the last frame would wait for 36. (A wall-clock bound, 1 s
// for four frames of 100 ms, failed beside Chromium under ASan: answers 1.5-2.0 s late.)
TEST_F(ClientSessionTest, ASlowLinkDropsTheOldestFramesOnTheRobotSide) {
  engine_delay_ms_ = 100;
  SessionOptions options = Options();
  options.frame_deadline = std::chrono::milliseconds(5000);
  auto session = Session::Open(options);
  std::map<int64_t, std::chrono::steady_clock::time_point> submitted;
  for (int i = 0; i < 40; ++i) {
    submitted[MakeFrame(i).timestamp_ns] = std::chrono::steady_clock::now();
    ASSERT_TRUE(session->Submit(MakeFrame(i)));
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  session->Close(std::chrono::milliseconds(3000));
  const std::vector<Event> events = Collect(session.get(), 1, [](const auto&) { return false; });
  const int answered = Count(events, Event::Kind::kResult);
  const int dropped = Count(events, Event::Kind::kDropped);
  EXPECT_EQ(answered + dropped, 40);
  EXPECT_GE(dropped, 25);
  EXPECT_GE(answered, 4);
  std::lock_guard<std::mutex> lock(engine_mutex_);
  for (const Event& e : events) {
    if (e.kind == Event::Kind::kResult) {
      const auto taken = std::find_if(engine_starts_.begin(), engine_starts_.end(),
                                      [&](const auto& s) { return s.first == e.timestamp_ns; });
      ASSERT_NE(taken, engine_starts_.end()) << e.timestamp_ns;
      const auto before = std::count_if(engine_starts_.begin(), taken, [&](const auto& s) {
        return s.second >= submitted.at(e.timestamp_ns);
      });
      EXPECT_LE(before, options.max_in_flight + options.max_queued)
          << "frames the engine took between frame " << e.timestamp_ns
          << "'s Submit and its own; its latency " << e.latency_ms << " ms";
    } else if (e.kind == Event::Kind::kDropped) {
      EXPECT_THAT(e.detail, HasSubstr("slower than the camera"));
    }
  }
}

// The frames a slow link drops on the robot side hand their gyro samples to the next frame sent:
// each frame's samples cover only the time since the frame before it, and the engine integrates
// the rotation since the last frame it saw. Without the hand-over it would hold one rate across
// the gap.
TEST_F(ClientSessionTest, DroppedFramesHandTheirGyroSamplesToTheNextFrameSent) {
  engine_delay_ms_ = 100;
  SessionOptions options = Options();
  options.frame_deadline = std::chrono::milliseconds(5000);
  auto session = Session::Open(options);
  std::vector<int64_t> sent_ns;
  for (int i = 0; i < 20; ++i) {
    Frame frame = MakeFrame(i);
    for (int64_t before_ns : {10'000'000, 5'000'000, 0}) {  // A 200 Hz gyro.
      v1::ImuSample sample;
      sample.set_timestamp_ns(frame.timestamp_ns - before_ns);
      sample.set_gyro_z(0.5);
      frame.imu.push_back(sample);
      sent_ns.push_back(sample.timestamp_ns());
    }
    ASSERT_TRUE(session->Submit(frame));
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  session->Close(std::chrono::milliseconds(3000));
  const std::vector<Event> events = Collect(session.get(), 1, [](const auto&) { return false; });
  const int dropped = Count(events, Event::Kind::kDropped);
  ASSERT_GT(dropped, 0) << "the link kept up: nothing was carried";
  EXPECT_EQ(Count(events, Event::Kind::kResult) + dropped, 20);
  // The newest frame is never the one dropped: every sample reached the engine, once, in order.
  std::lock_guard<std::mutex> lock(engine_mutex_);
  EXPECT_EQ(engine_imu_ns_, sent_ns) << dropped << " of 20 frames dropped";
}

TEST_F(ClientSessionTest, ARefusedSessionFailsOnceWithTheServersReason) {
  auto session = Session::Open(Options("nope"));
  for (int i = 0; i < 3; ++i) {  // A camera goes on giving frames while the refusal comes.
    session->Submit(MakeFrame(i));
    std::this_thread::sleep_for(std::chrono::milliseconds(30));
  }
  const std::vector<Event> events = Collect(session.get(), 10, [](const auto& e) {
    return !e.empty() && e.back().kind == Event::Kind::kLinkState &&
           e.back().link_state == LinkState::kFailed;
  });
  ASSERT_FALSE(events.empty());
  EXPECT_EQ(events.back().link_state, LinkState::kFailed);
  EXPECT_THAT(events.back().detail, HasSubstr("no map named 'nope'"));
  EXPECT_THAT(events.back().detail, HasSubstr("gRPC code 5"));
  // Frames sent before the refusal came say why they were never answered (a load test counts
  // a capacity refusal's frames as awaiting admission, not as lost by the link).
  int undelivered = 0;
  for (const Event& e : events) {
    if (e.kind != Event::Kind::kUndelivered) continue;
    ++undelivered;
    EXPECT_THAT(e.detail, HasSubstr("no map named 'nope'"));
  }
  EXPECT_GT(undelivered, 0) << "the frames went out before the refusal came";
  std::string why;
  EXPECT_FALSE(session->Submit(MakeFrame(1), &why));
  EXPECT_THAT(why, HasSubstr("no map named 'nope'"));
  EXPECT_EQ(session->stats().streams_opened, 1u);  // No reconnecting to a refusal.
}

// A replay that hands over its frames and closes at once, before the first stream is even
// open: the drain still connects and every frame is answered.
TEST_F(ClientSessionTest, CloseRightAfterSubmitStillDeliversEveryFrame) {
  SessionOptions options = Options();
  options.wait_for_room = true;
  auto session = Session::Open(options);
  ASSERT_TRUE(session->Submit(MakeFrame(0)));
  session->Close(std::chrono::milliseconds(10000));
  EXPECT_EQ(session->stats().answered, 1u);
  EXPECT_EQ(session->stats().dropped, 0u);
}

TEST_F(ClientSessionTest, BadOptionsAndFramesAreRefusedAtOnce) {
  SessionOptions no_map = Options();
  no_map.map_name.clear();
  EXPECT_THROW(Session::Open(no_map), std::invalid_argument);
  auto session = Session::Open(Options());
  Frame wrong = MakeFrame(0);
  wrong.image = cv::Mat(100, 100, CV_8UC1, cv::Scalar(0));
  std::string why;
  EXPECT_FALSE(session->Submit(wrong, &why));
  EXPECT_EQ(why, "the image is 100x100 but the session camera is 160x120");
  EXPECT_FALSE(session->Submit(Frame{}, &why));
  EXPECT_EQ(why, "the frame has no image");
}

// A rig: the session declares its rear camera, every frame carries its image (each encoding),
// and the server answers every frame with each camera's share; frames that do not fit the rig
// are refused at once, on the robot's side.
TEST_F(ClientSessionTest, ARigSessionSendsEveryCamerasImageAndHearsEachOnesShare) {
  for (const Encoding encoding : {Encoding::kJpeg, Encoding::kRaw}) {
    SessionOptions options = Options();
    options.encoding = encoding;
    options.wait_for_room = true;
    v1::RigCamera& rear = options.rig_cameras.emplace_back();
    *rear.mutable_camera() = options.camera;
    rear.mutable_body_from_cam()->set_qy(1.0);  // Half a turn about y: looking back.
    auto session = Session::Open(options);
    std::string why;
    EXPECT_FALSE(session->Submit(MakeFrame(0), &why));
    EXPECT_EQ(why, "the frame carries 0 rig images for 1 rig cameras");
    Frame wrong = MakeFrame(0);
    wrong.rig_images.push_back({wrong.timestamp_ns, cv::Mat(10, 10, CV_8UC1, cv::Scalar(0)), ""});
    EXPECT_FALSE(session->Submit(wrong, &why));
    EXPECT_EQ(why, "rig camera 1's image is 10x10 but that camera is 160x120 (8-bit)");
    for (int i = 0; i < 3; ++i) {
      Frame frame = MakeFrame(i);
      frame.rig_images.push_back({frame.timestamp_ns, MakeFrame(i + 10).image, ""});
      ASSERT_TRUE(session->Submit(frame, &why)) << why;
    }
    const std::vector<Event> events = Collect(
        session.get(), 20, [](const auto& e) { return Count(e, Event::Kind::kResult) == 3; });
    session->Close();
    int answered = 0;
    for (const Event& e : events) {
      if (e.kind != Event::Kind::kResult) continue;
      EXPECT_NE(e.response.status(), v1::STATUS_ERROR) << e.response.error();
      // Random images: nothing to localize. Both cameras are named in every answer, and the
      // first frame's features were extracted in both (a robot that stays lost then goes
      // straight to the relocalization features).
      ASSERT_EQ(e.response.cameras_size(), 2) << static_cast<int>(encoding);
      if (answered == 0) {
        EXPECT_GT(e.response.cameras(1).features(), 0u);
      }
      ++answered;
    }
    EXPECT_EQ(answered, 3);
  }
}

TEST_F(ClientSessionTest, AnUnreachableServerIsRetriedThenGivenUpWhenAsked) {
  SessionOptions options = Options();
  options.server = "127.0.0.1:1";  // Nothing listens there.
  options.connect_timeout = std::chrono::milliseconds(100);
  options.give_up_after = std::chrono::milliseconds(600);
  auto session = Session::Open(options);
  const std::vector<Event> events = Collect(session.get(), 10, [](const auto& e) {
    return !e.empty() && e.back().kind == Event::Kind::kLinkState &&
           e.back().link_state == LinkState::kFailed;
  });
  ASSERT_FALSE(events.empty());
  EXPECT_EQ(events.back().link_state, LinkState::kFailed);
  EXPECT_THAT(events.back().detail, HasSubstr("gave up after 600 ms"));
  EXPECT_EQ(session->stats().streams_opened, 0u);
}

}  // namespace
}  // namespace visloc::client
