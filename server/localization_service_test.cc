#include "server/localization_service.h"

#include <gmock/gmock.h>
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <atomic>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

#include <opencv2/core.hpp>

#include "core/util/temp_dir.h"
#include "server/test_session.h"

namespace visloc::server {
namespace {

// A service on an in-process channel over a small synthetic map "lab", with a session helper.
class ServiceFixture : public ::testing::Test {
 protected:
  // `before_frame` is the fault-injection hook, installed before the server starts serving.
  void Start(const ServiceLimits& limits, BeforeFrameHook before_frame = nullptr) {
    testing::WriteLabMap(maps_dir_.path());
    maps_ = std::make_unique<MapCache>(maps_dir_.path(), std::chrono::seconds(60));
    service_ = std::make_unique<LocalizationService>(maps_.get(), limits, &auth_);
    if (before_frame) service_->SetBeforeFrameHookForTesting(std::move(before_frame));
    grpc::ServerBuilder builder;
    builder.RegisterService(service_.get());
    server_ = builder.BuildAndStart();
    channel_ = server_->InProcessChannel(grpc::ChannelArguments());
  }
  void TearDown() override {
    if (server_) server_->Shutdown();
  }
  // A Localize call on "lab" whose SessionStart is sent (the call keeps the channel, not the stub).
  std::unique_ptr<grpc::ClientReaderWriter<v1::LocalizeRequest, v1::LocalizeResponse>> OpenSession(
      grpc::ClientContext* context, v1::FrameDropPolicy policy = v1::PROCESS_ALL) const {
    auto stream = v1::Localization::NewStub(channel_)->Localize(context);
    EXPECT_TRUE(stream->Write(testing::StartRequest(policy)));
    return stream;
  }

  TempDir maps_dir_{"visloc-service-test"};
  const TokenAuth auth_;
  std::unique_ptr<MapCache> maps_;
  std::unique_ptr<LocalizationService> service_;
  std::unique_ptr<grpc::Server> server_;
  std::shared_ptr<grpc::Channel> channel_;
};

// Four sessions stream at once into a service with one worker permit: every frame is answered,
// and never more than one is processed at a time (the permits bound the CPU work, not the
// sessions).
TEST_F(ServiceFixture, ConcurrentSessionsShareTheWorkerPermits) {
  ServiceLimits limits;
  limits.workers = 1;
  Start(limits);
  constexpr int kSessions = 4, kFrames = 10;
  std::vector<int> answered(kSessions, 0);
  std::vector<std::thread> robots;
  for (int r = 0; r < kSessions; ++r) {
    robots.emplace_back([&, r] {
      grpc::ClientContext context;
      auto stream = OpenSession(&context);
      for (int i = 0; i < kFrames; ++i) {
        v1::LocalizeResponse response;
        if (!stream->Write(testing::FrameRequest(i)) || !stream->Read(&response)) return;
        answered[r] += response.status() != v1::STATUS_ERROR;
      }
      stream->WritesDone();
      EXPECT_TRUE(stream->Finish().ok());
    });
  }
  for (std::thread& robot : robots) robot.join();
  for (int r = 0; r < kSessions; ++r) EXPECT_EQ(answered[r], kFrames) << "session " << r;
  EXPECT_EQ(service_->peak_frames_in_work(), 1);
  EXPECT_EQ(service_->active_sessions(), 0);
}

class EngineFaultTest : public ServiceFixture,
                        public ::testing::WithParamInterface<v1::FrameDropPolicy> {};

// The engine throws what it never should (not an InputError) on every other frame: those frames
// are answered STATUS_ERROR with a log reference and nothing of the exception's text, the others
// are answered normally, and the server goes on serving new sessions. Under NEWEST_ONLY the
// exception is raised while the live reader thread runs: it must not unwind past it.
TEST_P(EngineFaultTest, AnExceptionInTheEngineIsOneFramesErrorNotTheServers) {
  std::atomic<int> calls{0};
  Start(ServiceLimits{}, [&calls](const v1::Frame&) {
    if (calls++ % 2 == 0) throw std::runtime_error("injected fault at engine.cc:42");
  });
  for (int session = 0; session < 2; ++session) {
    grpc::ClientContext context;
    auto stream = OpenSession(&context, GetParam());
    int errors = 0, answered = 0;
    for (int i = 0; i < 6; ++i) {
      v1::LocalizeResponse response;
      ASSERT_TRUE(stream->Write(testing::FrameRequest(i)));
      ASSERT_TRUE(stream->Read(&response));  // One frame in flight: never dropped as stale.
      if (response.status() == v1::STATUS_ERROR) {
        ++errors;
        EXPECT_THAT(response.error(), ::testing::HasSubstr("internal server error (reference "));
        EXPECT_THAT(response.error(), ::testing::Not(::testing::HasSubstr("engine.cc")));
      } else {
        ++answered;
      }
    }
    stream->WritesDone();
    EXPECT_TRUE(stream->Finish().ok());
    EXPECT_EQ(errors, 3) << "session " << session;
    EXPECT_EQ(answered, 3) << "session " << session;
  }
  EXPECT_EQ(service_->active_sessions(), 0);
}

INSTANTIATE_TEST_SUITE_P(BothDropPolicies, EngineFaultTest,
                         ::testing::Values(v1::PROCESS_ALL, v1::NEWEST_ONLY));

// Frames the server skips (NEWEST_ONLY behind a slow engine) hand their gyro samples to the
// next frame it answers: each frame's samples cover only the time since the frame before it, and
// the engine integrates the rotation since the last frame it saw. Without the hand-over the
// engine would hold one rate across the whole gap.
TEST_F(ServiceFixture, SkippedFramesHandTheirGyroSamplesToTheNextFrameAnswered) {
  std::mutex mutex;
  std::vector<int64_t> seen_ns;  // The sample stamps the engine got, in order.
  Start(ServiceLimits{}, [&](const v1::Frame& frame) {
    std::this_thread::sleep_for(std::chrono::milliseconds(40));
    std::lock_guard<std::mutex> lock(mutex);
    for (const v1::ImuSample& sample : frame.imu()) seen_ns.push_back(sample.timestamp_ns());
  });
  grpc::ClientContext context;
  auto stream = OpenSession(&context, v1::NEWEST_ONLY);
  constexpr int kFrames = 20;
  std::vector<int64_t> sent_ns;
  for (int i = 0; i < kFrames; ++i) {
    v1::LocalizeRequest request = testing::FrameRequest(i);
    for (int64_t before_ns : {10'000'000, 5'000'000, 0}) {  // A 200 Hz gyro.
      v1::ImuSample* sample = request.mutable_frame()->add_imu();
      sample->set_timestamp_ns(request.frame().timestamp_ns() - before_ns);
      sample->set_gyro_z(0.5);
      sent_ns.push_back(sample->timestamp_ns());
    }
    ASSERT_TRUE(stream->Write(request));
  }
  stream->WritesDone();
  int skipped = 0;
  v1::LocalizeResponse response;
  while (stream->Read(&response)) {
    EXPECT_NE(response.status(), v1::STATUS_ERROR) << response.error();
    if (response.status() == v1::STATUS_SKIPPED) ++skipped;
  }
  EXPECT_TRUE(stream->Finish().ok());
  ASSERT_GT(skipped, 0) << "the engine kept up: nothing was carried";
  // The last frame is always answered (the newest of its batch): every sample reached the
  // engine, once, in order.
  std::lock_guard<std::mutex> lock(mutex);
  EXPECT_EQ(seen_ns, sent_ns) << skipped << " of " << kFrames << " frames skipped";
}

// A robot whose link froze keeps its stream open and sends nothing: after the idle timeout the
// server ends the session with a last STATUS_CLOSED answer naming the timeout, and its slot (the
// only one) takes a new robot. The timeout is long enough that a frame never takes it to arrive,
// even on a loaded machine under ThreadSanitizer (at 0.3 s, a CI run saw the first frame's answer
// be the closing one).
TEST_F(ServiceFixture, AFrozenSessionIsClosedAfterTheIdleTimeoutAndItsSlotFreed) {
  ServiceLimits limits;
  limits.max_sessions = 1;
  limits.session_idle_timeout = std::chrono::milliseconds(2000);
  Start(limits);
  grpc::ClientContext frozen_context;
  auto frozen = OpenSession(&frozen_context);
  v1::LocalizeResponse response;
  ASSERT_TRUE(frozen->Write(testing::FrameRequest(0)));
  ASSERT_TRUE(frozen->Read(&response));
  ASSERT_NE(response.status(), v1::STATUS_CLOSED) << response.error();
  // Then nothing: the next answer is the server closing the session.
  const auto before = std::chrono::steady_clock::now();
  ASSERT_TRUE(frozen->Read(&response));
  const double waited_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - before).count();
  EXPECT_EQ(response.status(), v1::STATUS_CLOSED);
  EXPECT_THAT(response.error(), ::testing::HasSubstr("no frame for 2.0 s"));
  // The clock started when the server sent the answer, a little before we read it.
  EXPECT_GE(waited_s, 1.0);
  EXPECT_LT(waited_s, 10.0);
  EXPECT_FALSE(frozen->Read(&response));
  frozen->Finish();
  for (int i = 0; i < 1000 && service_->active_sessions() > 0; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  EXPECT_EQ(service_->idle_sessions_closed(), 1);
  // The slot is free: a new robot is served.
  grpc::ClientContext next_context;
  auto next = OpenSession(&next_context);
  ASSERT_TRUE(next->Write(testing::FrameRequest(0)));
  ASSERT_TRUE(next->Read(&response));
  EXPECT_NE(response.status(), v1::STATUS_ERROR) << response.error();
  next->WritesDone();
  EXPECT_TRUE(next->Finish().ok());
}

// A robot that is slow to read (its link stalls while the server closes the idle session) still
// finds the closing answer when it reads again: the server's cancellation of the call, which
// follows the answer, does not discard it.
TEST_F(ServiceFixture, AClientSlowToReadStillGetsTheClosingAnswer) {
  ServiceLimits limits;
  limits.session_idle_timeout = std::chrono::milliseconds(200);
  Start(limits);
  grpc::ClientContext context;
  auto stream = OpenSession(&context);
  std::this_thread::sleep_for(std::chrono::milliseconds(600));  // Closed by now.
  v1::LocalizeResponse response;
  ASSERT_TRUE(stream->Read(&response));
  EXPECT_EQ(response.status(), v1::STATUS_CLOSED);
  EXPECT_THAT(response.error(), ::testing::HasSubstr("no frame for 0.2 s"));
  EXPECT_FALSE(stream->Read(&response));
  stream->Finish();
}

}  // namespace
}  // namespace visloc::server
