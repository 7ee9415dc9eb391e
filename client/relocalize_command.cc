// `visloc relocalize`: one image, no session. The server finds the camera anywhere in the map
// (appearance retrieval + geometric verification) or says clearly that it could not.

#include <grpcpp/grpcpp.h>

#include <cstdio>
#include <iostream>

#include "client/commands.h"
#include "client/connection.h"
#include "core/util/args.h"
#include "core/util/check.h"
#include "core/util/json.h"
#include "core/util/strings.h"
#include "core/util/text_file.h"
#include "dataset/dataset.h"
#include "proto/convert.h"
#include "visloc/v1/visloc.grpc.pb.h"

namespace visloc::cli {

int RunRelocalize(const Args& raw_args) {
  std::string map_name, image_path, dataset_dir;
  Connection server;
  bool json = false;
  ArgParser parser("visloc relocalize",
                   "Asks visloc-server where one image was taken in a map: prints the pose with "
                   "its evidence and the ranked candidate keyframes, or 'not localized' (exit 3). "
                   "The image is taken to come from the map's camera unless --dataset names the "
                   "dataset whose left camera took it.");
  server.AddFlags(parser);
  parser.AddFlag("map", &map_name, "map name on the server", true);
  parser.AddFlag("dataset", &dataset_dir, "dataset whose left camera took the image");
  parser.AddPositional("IMAGE", &image_path, "PNG or JPEG image", true);
  parser.AddSwitch("json", &json, "print one JSON object");
  if (!parser.Parse(raw_args, std::cout)) return 0;
  server.ApplyEnvironment();
  v1::RelocalizeRequest request;
  request.set_map_name(map_name);
  if (!dataset_dir.empty()) {
    proto::ToProto(ReadDataset(dataset_dir).left.camera, request.mutable_camera());
  }
  request.set_encoded_image(ReadFileBytes(image_path));
  auto stub = v1::Localization::NewStub(server.OpenChannel());
  grpc::ClientContext context;
  server.Prepare(&context);
  v1::RelocalizeResponse response;
  const grpc::Status status = stub->Relocalize(&context, request, &response);
  CheckCall(status, server.server);
  const v1::Pose& p = response.map_from_cam();
  if (json) {
    JsonWriter out;
    out.BeginObject().Field("localized", response.localized()).Field("ms", response.ms());
    if (response.localized()) {
      out.Field("inliers", static_cast<int64_t>(response.inliers()))
          .Field("inlier_ratio", response.inlier_ratio())
          .Field("keyframe", static_cast<int64_t>(response.keyframe()));
      out.Key("map_from_cam")
          .BeginObject()
          .Field("tx", p.tx())
          .Field("ty", p.ty())
          .Field("tz", p.tz())
          .Field("qw", p.qw())
          .Field("qx", p.qx())
          .Field("qy", p.qy())
          .Field("qz", p.qz())
          .EndObject();
    }
    out.Key("candidates").BeginArray();
    for (const auto& c : response.candidates()) {
      out.BeginObject()
          .Field("keyframe", static_cast<int64_t>(c.keyframe()))
          .Field("score", c.score())
          .Field("matches", static_cast<int64_t>(c.matches()))
          .Field("verified_inliers", static_cast<int64_t>(c.verified_inliers()))
          .Field("accepted", c.accepted())
          .EndObject();
    }
    out.EndArray().EndObject();
    std::cout << out.str() << "\n";
  } else if (response.localized()) {
    std::printf(
        "localized in %.1f ms: position (%.3f, %.3f, %.3f) m, quaternion (w %.4f, x %.4f, "
        "y %.4f, z %.4f); %u inliers (ratio %.2f) via keyframe %d\n",
        response.ms(), p.tx(), p.ty(), p.tz(), p.qw(), p.qx(), p.qy(), p.qz(), response.inliers(),
        response.inlier_ratio(), response.keyframe());
  } else {
    std::printf("not localized (%.1f ms, %d candidates checked)\n", response.ms(),
                response.candidates_size());
  }
  if (!json) {
    for (const auto& c : response.candidates()) {
      std::printf("  candidate keyframe %4d  score %.3f  matches %3u  verified inliers %3u%s\n",
                  c.keyframe(), c.score(), c.matches(), c.verified_inliers(),
                  c.accepted() ? "  accepted" : "");
    }
  }
  return response.localized() ? 0 : 3;
}

}  // namespace visloc::cli
