#include "server/localization_service.h"

#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <thread>
#include <vector>

#include <opencv2/core.hpp>

#include "core/map/synthetic_map.h"
#include "core/util/temp_dir.h"
#include "mapstore/map_store.h"
#include "proto/convert.h"

namespace visloc::server {
namespace {

// Four sessions stream at once into a service with one worker permit: every frame is answered,
// and never more than one is processed at a time (the permits bound the CPU work, not the
// sessions).
TEST(LocalizationServiceTest, ConcurrentSessionsShareTheWorkerPermits) {
  TempDir maps_dir("visloc-service-test");
  SyntheticMapOptions options;
  options.keyframes = 6;
  options.points = 300;
  Map map = MakeSyntheticMap(options);
  map.metadata.name = "lab";
  mapstore::SaveMap(map, maps_dir.File("lab.db"), mapstore::SaveMapOptions{4096});
  MapCache maps(maps_dir.path(), std::chrono::seconds(60));
  ServiceLimits limits;
  limits.workers = 1;
  const TokenAuth auth;
  LocalizationService service(&maps, limits, &auth);
  grpc::ServerBuilder builder;
  builder.RegisterService(&service);
  const std::unique_ptr<grpc::Server> server = builder.BuildAndStart();
  const auto channel = server->InProcessChannel(grpc::ChannelArguments());

  const Camera camera(160, 120, 80.0, 80.0, 79.5, 59.5);
  cv::Mat image(camera.height(), camera.width(), CV_8UC1);
  cv::randu(image, 0, 255);
  constexpr int kSessions = 4, kFrames = 10;
  std::vector<int> answered(kSessions, 0);
  std::vector<std::thread> robots;
  for (int r = 0; r < kSessions; ++r) {
    robots.emplace_back([&, r] {
      auto stub = v1::Localization::NewStub(channel);
      grpc::ClientContext context;
      auto stream = stub->Localize(&context);
      v1::LocalizeRequest start;
      start.mutable_start()->set_map_name("lab");
      proto::ToProto(camera, start.mutable_start()->mutable_camera());
      if (!stream->Write(start)) return;
      for (int i = 0; i < kFrames; ++i) {
        v1::LocalizeRequest frame;
        frame.mutable_frame()->set_timestamp_ns((i + 1) * 66'666'667LL);
        v1::RawImage* raw = frame.mutable_frame()->mutable_raw();
        raw->set_width(image.cols);
        raw->set_height(image.rows);
        raw->set_pixels(image.data, image.total());
        v1::LocalizeResponse response;
        if (!stream->Write(frame) || !stream->Read(&response)) return;
        answered[r] += response.status() != v1::STATUS_ERROR;
      }
      stream->WritesDone();
      EXPECT_TRUE(stream->Finish().ok());
    });
  }
  for (std::thread& robot : robots) robot.join();
  for (int r = 0; r < kSessions; ++r) EXPECT_EQ(answered[r], kFrames) << "session " << r;
  EXPECT_EQ(service.peak_frames_in_work(), 1);
  EXPECT_EQ(service.active_sessions(), 0);
}

}  // namespace
}  // namespace visloc::server
