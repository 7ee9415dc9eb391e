// `visloc relocalize`: images with no session. The server finds each camera anywhere in the map
// (appearance retrieval + geometric verification) or says clearly that it could not. One image,
// or each of a dataset's frames alone (a kidnapped robot's first image, over a whole recording).

#include <grpcpp/grpcpp.h>

#include <cstdio>
#include <iostream>

#include "client/commands.h"
#include "client/connection.h"
#include "client/dataset_frames.h"
#include "client/relocalization_evidence.h"
#include "core/eval/trajectory_eval.h"
#include "core/util/args.h"
#include "core/util/check.h"
#include "core/util/json.h"
#include "core/util/strings.h"
#include "core/util/text_file.h"
#include "dataset/dataset.h"
#include "dataset/euroc.h"
#include "dataset/frame_range.h"
#include "dataset/tum.h"
#include "proto/convert.h"
#include "visloc/v1/visloc.grpc.pb.h"

namespace visloc::cli {
namespace {

struct RelocalizeArgs {
  std::string map_name, image_path, dataset_dir, sensor_path, frames, trajectory_path;
  std::string map_file, evidence_path;
  std::string cameras = "cam0";  // With --frames: the rig each request carries.
  Connection server;
  bool json = false;
};

// One Relocalize call for the image file at `path`, with `rig_images` (the files' bytes, or
// none for a camera without an image then) for a rig's other cameras.
v1::RelocalizeResponse Ask(
    v1::Localization::Stub& stub, const RelocalizeArgs& args, const v1::RelocalizeRequest& base,
    const std::string& path,
    const std::vector<std::optional<std::pair<int64_t, std::string>>>& rig_images = {}) {
  v1::RelocalizeRequest request = base;
  request.set_encoded_image(ReadFileBytes(path));
  for (const auto& image : rig_images) {
    v1::RigImage* out = request.add_rig_images();
    if (!image) continue;
    out->set_timestamp_ns(image->first);
    out->set_encoded(ReadFileBytes(image->second));
  }
  grpc::ClientContext context;
  args.server.Prepare(&context);
  v1::RelocalizeResponse response;
  CheckCall(stub.Relocalize(&context, request, &response), args.server.server);
  return response;
}

void WritePose(JsonWriter& out, const v1::Pose& p) {
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

// The fields of one answer, inside an open JSON object.
void WriteAnswer(JsonWriter& out, const v1::RelocalizeResponse& response) {
  out.Field("localized", response.localized())
      .Field("ms", response.ms())
      .Field("feature_passes", static_cast<int64_t>(response.feature_passes()));
  if (response.localized()) {
    out.Field("inliers", static_cast<int64_t>(response.inliers()))
        .Field("inlier_ratio", response.inlier_ratio())
        .Field("keyframe", static_cast<int64_t>(response.keyframe()));
    WritePose(out, response.map_from_cam());
  }
  out.Key("candidates").BeginArray();
  for (const auto& c : response.candidates()) {
    out.BeginObject()
        .Field("keyframe", static_cast<int64_t>(c.keyframe()))
        .Field("score", c.score())
        .Field("matches", static_cast<int64_t>(c.matches()))
        .Field("verified_inliers", static_cast<int64_t>(c.verified_inliers()))
        .Field("verified_putatives", static_cast<int64_t>(c.verified_putatives()))
        .Field("verified_inlier_ratio", c.verified_inlier_ratio())
        .Field("inlier_cells", static_cast<int64_t>(c.inlier_cells()))
        .Field("significance", c.significance())
        .Field("accepted", c.accepted())
        .EndObject();
  }
  out.EndArray();
}

void PrintAnswer(const v1::RelocalizeResponse& response) {
  const v1::Pose& p = response.map_from_cam();
  if (response.localized()) {
    std::printf(
        "localized in %.1f ms: position (%.3f, %.3f, %.3f) m, quaternion (w %.4f, x %.4f, "
        "y %.4f, z %.4f); %u inliers (ratio %.2f) via keyframe %d\n",
        response.ms(), p.tx(), p.ty(), p.tz(), p.qw(), p.qx(), p.qy(), p.qz(), response.inliers(),
        response.inlier_ratio(), response.keyframe());
  } else {
    std::printf("not localized (%.1f ms, %d candidates checked)\n", response.ms(),
                response.candidates_size());
  }
  for (const auto& c : response.candidates()) {
    std::printf(
        "  candidate keyframe %4d  score %.3f  matches %3u  verified inliers %3u of %3u, "
        "%2u cells, significance %.1f%s\n",
        c.keyframe(), c.score(), c.matches(), c.verified_inliers(), c.verified_putatives(),
        c.inlier_cells(), c.significance(), c.accepted() ? "  accepted" : "");
  }
}

int RelocalizeOneImage(v1::Localization::Stub& stub, const RelocalizeArgs& args,
                       const v1::RelocalizeRequest& base) {
  const v1::RelocalizeResponse response = Ask(stub, args, base, args.image_path);
  if (args.json) {
    JsonWriter out;
    out.BeginObject();
    WriteAnswer(out, response);
    out.EndObject();
    std::cout << out.str() << "\n";
  } else {
    PrintAnswer(response);
  }
  return response.localized() ? 0 : 3;
}

// Each selected frame of the dataset alone; the found poses optionally as a TUM trajectory.
int RelocalizeFrames(v1::Localization::Stub& stub, const RelocalizeArgs& args,
                     const v1::RelocalizeRequest& base, const Dataset& dataset) {
  Trajectory found;
  std::vector<v1::RelocalizeResponse> answers;
  std::vector<double> ms;
  const std::vector<std::string> cameras = ParseCameraNames(args.cameras);
  for (size_t i = 0; i < dataset.frames.size(); ++i) {
    const FrameRecord& frame = dataset.frames[i];
    std::vector<std::optional<std::pair<int64_t, std::string>>> rig_images;
    for (size_t c = 1; c < cameras.size(); ++c) {
      rig_images.push_back(
          CameraImageAt(dataset, cameras[c], i, LocalizerOptions{}.max_rig_skew_ns));
    }
    answers.push_back(Ask(stub, args, base, frame.left_path, rig_images));
    const v1::RelocalizeResponse& answer = answers.back();
    ms.push_back(answer.ms());
    if (answer.localized()) {
      found.push_back(
          {frame.timestamp_ns, proto::FromProto(answer.map_from_cam(), "map_from_cam")});
    }
    if (!args.json) {
      std::printf("%lld: %s (%.1f ms, %u inliers)\n", static_cast<long long>(frame.timestamp_ns),
                  answer.localized() ? "localized" : "not localized", answer.ms(),
                  answer.inliers());
    }
  }
  if (!args.trajectory_path.empty()) WriteTum(args.trajectory_path, found);
  const size_t total = dataset.frames.size();
  const ErrorStats time = ComputeErrorStats(ms);
  if (!args.json) {
    std::printf("localized %zu of %zu images, each alone (%.1f%%); server time median %.1f ms\n",
                found.size(), total, 100.0 * found.size() / total, time.median);
    return 0;
  }
  JsonWriter out;
  out.BeginObject()
      .Field("frames", static_cast<int64_t>(total))
      .Field("localized", static_cast<int64_t>(found.size()))
      .Field("localized_fraction", static_cast<double>(found.size()) / total)
      .Key("ms")
      .BeginObject()
      .Field("median", time.median)
      .Field("p95", time.p95)
      .Field("max", time.max)
      .EndObject();
  out.Key("frame_results").BeginArray();
  for (size_t i = 0; i < total; ++i) {
    out.BeginObject().Field("timestamp_ns", dataset.frames[i].timestamp_ns);
    WriteAnswer(out, answers[i]);
    out.EndObject();
  }
  out.EndArray().EndObject();
  std::cout << out.str() << "\n";
  return 0;
}

}  // namespace

int RunRelocalize(const Args& raw_args) {
  RelocalizeArgs args;
  ArgParser parser("visloc relocalize",
                   "Asks visloc-server where an image was taken in a map, with no session and "
                   "nothing known of the camera's whereabouts: prints the pose with its evidence "
                   "and the ranked candidate keyframes, or 'not localized' (exit 3). The image is "
                   "taken to come from the map's camera unless --dataset names the dataset whose "
                   "left camera took it, or --camera-yaml the camera's sensor.yaml. With --frames, "
                   "each of those frames of the --dataset is "
                   "asked alone, and --trajectory keeps the poses found.");
  args.server.AddFlags(parser, /*server_required=*/false);  // Not with --evidence.
  parser.AddFlag("map", &args.map_name, "map name on the server");
  parser.AddFlag("map-file", &args.map_file,
                 "with --evidence: the map file, in process (no server)");
  parser.AddFlag("evidence", &args.evidence_path,
                 "with --map-file, --dataset and --frames: write every candidate of both feature "
                 "passes, verified under no acceptance rule, as TSV (for choosing the rule: "
                 "scripts/relocalization-rule.sh)");
  parser.AddFlag("dataset", &args.dataset_dir, "dataset whose left camera took the image(s)");
  parser.AddFlag("camera-yaml", &args.sensor_path,
                 "or the camera's sensor.yaml (EuRoC's, as visloc calibrate writes it)");
  parser.AddFlag("frames", &args.frames,
                 "with --dataset and no IMAGE: its frames to relocalize, each alone: N (the first "
                 "N), BEGIN:END or BEGIN:END:STEP; 'all' for every frame");
  parser.AddFlag("trajectory", &args.trajectory_path,
                 "with --frames: write the poses found (TUM, map frame)");
  parser.AddFlag("cameras", &args.cameras,
                 "with --frames: each request a rig's frame, cam0 (the reference) then others, "
                 "e.g. cam0,cam1 (the stereo pair)");
  parser.AddPositional("IMAGE", &args.image_path, "PNG or JPEG image", /*required=*/false);
  parser.AddSwitch("json", &args.json, "print one JSON object");
  if (!parser.Parse(raw_args, std::cout)) return 0;
  const bool many = !args.frames.empty();
  if (!args.evidence_path.empty()) {
    if (args.map_file.empty() || args.dataset_dir.empty() || !many) {
      throw UsageError("--evidence needs --map-file, --dataset and --frames");
    }
    const size_t rows = WriteRelocalizationEvidence(
        args.map_file,
        SelectFrames(ReadDataset(args.dataset_dir),
                     ParseFrameRange(args.frames == "all" ? "" : args.frames)),
        args.evidence_path);
    if (args.json) {
      JsonWriter out;
      out.BeginObject()
          .Field("evidence", args.evidence_path)
          .Field("rows", static_cast<int64_t>(rows))
          .EndObject();
      std::cout << out.str() << "\n";
    } else {
      std::printf("%zu candidate rows -> %s\n", rows, args.evidence_path.c_str());
    }
    return 0;
  }
  if (!args.map_file.empty()) throw UsageError("--map-file goes with --evidence");
  if (args.map_name.empty()) throw UsageError("--map is required");
  if (args.server.server.empty()) throw UsageError("--server is required");
  if (many == !args.image_path.empty()) {
    throw UsageError("give either IMAGE or --frames (with --dataset)");
  }
  if (many && args.dataset_dir.empty()) throw UsageError("--frames needs --dataset");
  if (!args.dataset_dir.empty() && !args.sensor_path.empty()) {
    throw UsageError("give --dataset or --camera-yaml, not both");
  }
  if (!many && !args.trajectory_path.empty()) throw UsageError("--trajectory needs --frames");
  if (args.cameras != "cam0" && (!many || args.dataset_dir.empty())) {
    throw UsageError("--cameras needs --dataset and --frames (a rig's images of each frame)");
  }
  args.server.ApplyEnvironment();
  v1::RelocalizeRequest base;
  base.set_map_name(args.map_name);
  std::optional<Dataset> dataset;
  if (!args.dataset_dir.empty()) {
    dataset = ReadDataset(args.dataset_dir);
    proto::ToProto(dataset->left.camera, base.mutable_camera());
    const std::vector<std::string> cameras = ParseCameraNames(args.cameras);
    if (cameras.size() > 1) {
      for (const v1::RigCamera& camera :
           WireRigCameras(DatasetCameraRig(*dataset, cameras, /*gyro=*/false), cameras)) {
        *base.add_rig_cameras() = camera;
      }
      proto::ToProto(dataset->left.body_from_cam, base.mutable_body_from_cam());
    }
  } else if (!args.sensor_path.empty()) {
    proto::ToProto(ReadSensorYaml(args.sensor_path).camera, base.mutable_camera());
  }
  auto stub = v1::Localization::NewStub(args.server.OpenChannel());
  if (!many) return RelocalizeOneImage(*stub, args, base);
  return RelocalizeFrames(
      *stub, args, base,
      SelectFrames(std::move(*dataset), ParseFrameRange(args.frames == "all" ? "" : args.frames)));
}

}  // namespace visloc::cli
