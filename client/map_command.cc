// visloc map info|verify|export|list|delete|rename: offline management of map files and of a
// maps folder. (The --server forms arrive with the gRPC service.)

#include <sys/resource.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <optional>

#include "client/commands.h"
#include "client/map_report.h"
#include "client/outcome.h"
#include "client/remote_map.h"
#include "client/remote_mapping.h"
#include "client/subcommands.h"
#include "core/util/args.h"
#include "core/util/check.h"
#include "core/util/json.h"
#include "core/util/strings.h"
#include "core/util/timer.h"
#include "core/util/version.h"
#include "dataset/dataset.h"
#include "dataset/euroc.h"
#include "dataset/frame_range.h"
#include "dataset/ply.h"
#include "dataset/tum.h"
#include "mapping/dataset_mapping.h"
#include "mapping/map_merge.h"
#include "mapstore/map_directory.h"
#include "mapstore/map_store.h"
#include "proto/mapping_convert.h"

namespace visloc::cli {
namespace {

// The wall time per frame in each quarter of a build's run, from its progress callback.
class QuarterClock {
 public:
  void Frame(int done, int total) {
    if (total < 4 || next_ >= 4 || done < (next_ + 1) * total / 4) return;
    const double ms = timer_.ElapsedMs();
    const int frames = (next_ + 1) * total / 4 - next_ * total / 4;
    frame_ms_.push_back((ms - last_ms_) / frames);
    last_ms_ = ms;
    ++next_;
  }
  const std::vector<double>& FrameMs() const { return frame_ms_; }

 private:
  Timer timer_;
  int next_ = 0;
  double last_ms_ = 0.0;
  std::vector<double> frame_ms_;
};

// The most memory the process has held resident, MiB.
double PeakResidentMib() {
  struct rusage usage {};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_maxrss / 1024.0;  // Linux counts KiB.
}

using mapstore::MapInfo;
namespace fs = std::filesystem;

// MAP.db, or NAME in --maps DIR.
// The folder verbs work on a local maps folder or on a server: exactly one of the two.
void RequireOneOf(const std::string& maps_dir, Connection& server) {
  server.ApplyEnvironment();
  if (maps_dir.empty() == server.server.empty())
    throw UsageError("give either --maps DIR or --server ADDR");
}

std::string ResolveMap(const std::string& map_or_name, const std::string& maps_dir) {
  if (!maps_dir.empty() && mapstore::IsValidMapName(map_or_name) && !EndsWith(map_or_name, ".db")) {
    return mapstore::MapDirectory(maps_dir).PathOf(map_or_name);
  }
  return map_or_name;
}

int RunInfo(const Args& args) {
  std::string map, maps_dir;
  bool json = false;
  ArgParser parser("visloc map info",
                   "Counts, extent, camera, features, size and schema of a map.");
  Connection server;
  parser.AddPositional("MAP", &map, "a map file, or a map name with --maps or --server");
  parser.AddFlag("maps", &maps_dir, "maps folder in which to find MAP by name");
  server.AddFlags(parser, /*server_required=*/false);
  parser.AddSwitch("json", &json, "print one JSON object");
  if (!parser.Parse(args, std::cout)) return 0;
  server.ApplyEnvironment();
  if (!server.server.empty()) return RemoteMapInfo(server, map, json);
  const std::string path = ResolveMap(map, maps_dir);
  const MapInfo info = mapstore::SummarizeMap(mapstore::LoadMap(path), path);
  return PrintMapInfo(info, json);
}

int RunVerify(const Args& args) {
  std::string map, maps_dir;
  bool json = false;
  ArgParser parser("visloc map verify",
                   "Checks a map file: SQLite integrity, schema, references, value sanity and the "
                   "content checksum. Exits 0 when sound, 1 with the problems otherwise.");
  parser.AddPositional("MAP", &map, "a map file, or a map name with --maps");
  parser.AddFlag("maps", &maps_dir, "maps folder in which to find MAP by name");
  parser.AddSwitch("json", &json, "print one JSON object");
  if (!parser.Parse(args, std::cout)) return 0;
  const std::string path = ResolveMap(map, maps_dir);
  const mapstore::VerifyReport report = mapstore::VerifyMapFile(path);
  if (json) {
    JsonWriter writer;
    writer.BeginObject().Field("path", path).Field("ok", report.ok()).Key("problems").BeginArray();
    for (const std::string& problem : report.problems) writer.Value(problem);
    writer.EndArray().EndObject();
    std::cout << writer.str() << "\n";
  } else if (report.ok()) {
    std::printf("%s: ok\n", path.c_str());
  }
  if (!report.ok() && !json) {
    for (const std::string& problem : report.problems)
      std::cerr << "visloc map verify: " << problem << "\n";
  }
  return report.ok() ? 0 : 1;
}

int RunExport(const Args& args) {
  std::string map, maps_dir, keyframes_path, ply_path;
  ArgParser parser(
      "visloc map export",
      "Writes a map's keyframe poses (TUM) and/or a PLY point cloud with the points (grey) and "
      "keyframe positions (red) for MeshLab or CloudCompare, in the map frame (as trajectories "
      "and ground truth are) or, with --frame site, in the site frame (z up: the frame `map "
      "align` tied it to, else the map's level frame).");
  parser.AddPositional("MAP", &map, "a map file, or a map name with --maps");
  parser.AddFlag("maps", &maps_dir, "maps folder in which to find MAP by name");
  parser.AddFlag("keyframes", &keyframes_path, "TUM file of keyframe poses to write");
  parser.AddFlag("ply", &ply_path, "PLY file to write");
  // The map frame by default while trajectories (localize, stream) are in it too: the surfaces
  // move to the site frame together.
  std::string frame = "map";
  parser.AddFlag("frame", &frame,
                 "map (the first camera's) or site (z up, when the map knows up; else the map "
                 "frame)");
  bool json = false;
  parser.AddSwitch("json", &json, "print one JSON object");
  if (!parser.Parse(args, std::cout)) return 0;
  if (keyframes_path.empty() && ply_path.empty())
    throw UsageError("nothing to export: give --keyframes and/or --ply");
  if (frame != "site" && frame != "map") throw UsageError("--frame must be site or map");
  const Map loaded = mapstore::LoadMap(ResolveMap(map, maps_dir));
  const std::optional<Rigid3d> site_from_map =
      frame == "site" ? SiteFromMap(loaded.metadata) : std::nullopt;
  const Rigid3d out_from_map = site_from_map.value_or(Rigid3d());
  const std::string written_frame = site_from_map ? "site" : "map";
  std::string written;  // One line per file written.
  if (!keyframes_path.empty()) {
    Trajectory keyframes;
    for (const Keyframe& k : loaded.keyframes) {
      keyframes.push_back({k.timestamp_ns, out_from_map * k.map_from_cam});
    }
    WriteTum(keyframes_path, keyframes);
    written =
        StrCat(keyframes.size(), " keyframe poses (", written_frame, " frame) -> ", keyframes_path);
  }
  if (!ply_path.empty()) {
    std::vector<ColoredPoint> cloud;
    cloud.reserve(loaded.points.size() + loaded.keyframes.size());
    for (const MapPoint& p : loaded.points) {
      cloud.push_back({out_from_map * p.position_in_map, {200, 200, 200}});
    }
    for (const Keyframe& k : loaded.keyframes) {
      cloud.push_back({out_from_map * k.map_from_cam.translation, {255, 0, 0}});
    }
    WritePly(ply_path, cloud,
             StrCat("visloc map ", loaded.metadata.name, ": ", loaded.points.size(),
                    " points (grey), ", loaded.keyframes.size(), " keyframes (red)"));
    written += StrCat(written.empty() ? "" : "\n", loaded.points.size(), " points and ",
                      loaded.keyframes.size(), " keyframes -> ", ply_path);
  }
  return PrintOutcome(json, written,
                      {{"map", loaded.metadata.name},
                       {"keyframes", static_cast<int64_t>(loaded.keyframes.size())},
                       {"points", static_cast<int64_t>(loaded.points.size())},
                       {"keyframes_tum", keyframes_path},
                       {"ply", ply_path},
                       {"frame", written_frame}});
}

// A flag's A,B: two finite numbers, or a usage error that says what the flag `wants`.
std::pair<double, double> ParseNumberPair(const std::string& text, const std::string& wants) {
  const std::vector<std::string> parts = Split(text, ',');
  const std::optional<double> a = parts.size() == 2 ? ParseDouble(parts[0]) : std::nullopt;
  const std::optional<double> b = parts.size() == 2 ? ParseDouble(parts[1]) : std::nullopt;
  if (!a || !b || !std::isfinite(*a) || !std::isfinite(*b)) {
    throw UsageError(StrCat(wants, ", got '", text, "'"));
  }
  return {*a, *b};
}

// --disparity-correction OFFSET_PX,YAW_DEG: a correction known for the rig.
std::optional<DisparityCorrection> ParseDisparityCorrection(const std::string& text) {
  if (text.empty()) return std::nullopt;
  const auto [offset_px, yaw_deg] = ParseNumberPair(
      text,
      "--disparity-correction wants OFFSET_PX,YAW_DEG (a build's disparity_offset_px and "
      "right_camera_yaw_deg)");
  return DisparityCorrection::FromDegrees(offset_px, yaw_deg);
}

// --rig-error FLOOR_M,DRIFT_FRACTION: how well the rig is calibrated (RigError, core/map/map.h).
std::optional<RigError> ParseRigError(const std::string& text) {
  if (text.empty()) return std::nullopt;
  const std::string wants = "--rig-error wants FLOOR_M,DRIFT_FRACTION, both at least 0";
  const auto [floor_m, drift_fraction] = ParseNumberPair(text, wants);
  if (floor_m < 0 || drift_fraction < 0) throw UsageError(StrCat(wants, ", got '", text, "'"));
  return RigError{floor_m, drift_fraction};
}

// The rig's correction a build is given: as numbers (--disparity-correction OFFSET_PX,YAW_DEG)
// or as the one a map of the same rig records (--disparity-correction-from MAP.db).
struct GivenCorrection {
  std::optional<DisparityCorrection> correction;
  std::string map_path;              // --disparity-correction-from, else empty.
  std::optional<Camera> map_camera;  // That map's camera.
};

GivenCorrection ParseGivenCorrection(const std::string& numbers, const std::string& map_path) {
  GivenCorrection given;
  given.correction = ParseDisparityCorrection(numbers);
  if (map_path.empty()) return given;
  if (given.correction) {
    throw UsageError("give --disparity-correction or --disparity-correction-from, not both");
  }
  const Map map = mapstore::LoadMap(map_path);
  if (!map.metadata.disparity_correction) {
    throw InputError(map_path +
                     " records no disparity correction (its build neither estimated nor was "
                     "given one, or an older visloc built it): give --disparity-correction "
                     "OFFSET_PX,YAW_DEG");
  }
  given.correction = map.metadata.disparity_correction;
  given.map_path = map_path;
  given.map_camera = map.camera;
  return given;
}

// A correction belongs to its rig: the map it came from must have the build's left camera.
void RequireCorrectionCamera(const GivenCorrection& given, const Camera& left) {
  if (given.map_camera && !mapping::SameCamera(*given.map_camera, left)) {
    throw InputError(StrCat("--disparity-correction-from ", given.map_path, ": the map's camera (",
                            ToString(*given.map_camera), ") is not this dataset's left camera (",
                            ToString(left), "): its correction is another rig's"));
  }
}

int RunBuild(const Args& args) {
  std::string dataset_dir, format, out, name, features = "harris_surf16", trajectory, frames;
  bool json = false;
  ArgParser parser("visloc map build",
                   "Builds a map from a stereo sequence (EuRoC or KITTI): stereo visual odometry, "
                   "keyframes, local and global bundle adjustment with loop closure, visibility "
                   "learning and the relocalization vocabulary.");
  parser.AddFlag("dataset", &dataset_dir, "stereo dataset folder");
  parser.AddFlag("format", &format, "euroc or kitti (default: detected)");
  parser.AddFlag("out", &out, "map file to write (without --server)");
  parser.AddFlag("name", &name,
                 "the map's name (default: the file name without .db; with --server, required)");
  Connection server;
  server.AddFlags(parser, /*server_required=*/false);
  parser.SetDefaultText("server",
                        "none: build here. With ADDR the server builds the map from "
                        "the streamed run and publishes it as NAME");
  bool replace = false;
  parser.AddSwitch("replace", &replace, "with --server: replace a map of that name on the server");
  bool extend = false;
  parser.AddSwitch("extend", &extend,
                   "with --server: add the run to the server's map NAME as a new session (as "
                   "visloc map extend) and replace it with the result");
  std::vector<std::string> cameras, camera_yamls;
  parser.AddList("camera", &cameras,
                 "with --server, instead of --dataset: the left and the right camera (a V4L2 "
                 "device, a GStreamer pipeline or a video file; --camera L --camera R); Ctrl-C "
                 "ends the run");
  parser.AddList("camera-yaml", &camera_yamls,
                 "with --camera: each camera's sensor.yaml (intrinsics, lens, T_BS), left then "
                 "right");
  std::string robot_id = "visloc-map-build";
  parser.AddFlag("robot-id", &robot_id, "with --server: the robot's name in the server's jobs");
  double resume_s = 30.0;
  parser.AddFlag("resume-s", &resume_s,
                 "with --server: how long a broken link is retried, the job resumed where the "
                 "server has it (0: give up at once)");
  double rate_hz = -1.0;
  parser.AddFlag("rate", &rate_hz,
                 "with --server: frames a second to stream at (0: the recording's own pace)");
  parser.SetDefaultText("rate", "as fast as the server maps");
  parser.AddFlag("features", &features, "harris_surf16 (the paper's) or orb");
  parser.AddFlag("frames", &frames,
                 "use only these frames: N (the first N), BEGIN:END or BEGIN:END:STEP");
  parser.AddFlag("trajectory", &trajectory,
                 "also write the estimated frame poses (TUM, map frame)");
  mapping::DatasetMappingOptions options;
  parser.AddFlag("keyframe-translation", &options.builder.keyframes.translation_m,
                 "new keyframe after this many metres");
  parser.AddFlag("keyframe-rotation", &options.builder.keyframes.rotation_deg,
                 "new keyframe after this many degrees");
  int loop_closure = 1;
  parser.AddFlag("loop-closure", &loop_closure, "1 to close loops, 0 not to");
  int disparity_calibration = 1;
  parser.AddFlag("disparity-calibration", &disparity_calibration,
                 "1 to estimate the rig's disparity bias (a right camera turned or its principal "
                 "point moved against the calibration) from the first frames' motion, 0 to trust "
                 "the calibration");
  std::string known_correction;
  parser.AddFlag("disparity-correction", &known_correction,
                 "OFFSET_PX,YAW_DEG: the rig's disparity correction as an earlier build "
                 "estimated it (its disparity_offset_px, right_camera_yaw_deg), taken off from "
                 "the first frame and not estimated again: each frame mapped once, and a run "
                 "too short to estimate it from mapped metrically");
  std::string correction_map;
  parser.AddFlag("disparity-correction-from", &correction_map,
                 "MAP.db: take the rig's disparity correction from a map an earlier build of "
                 "the same rig wrote (`map info` shows it), as --disparity-correction would");
  std::string rig_error;
  parser.AddFlag("rig-error", &rig_error,
                 "FLOOR_M,DRIFT_FRACTION: how well the rig is calibrated, as the position error "
                 "(per axis) it leaves in the map: a floor plus a fraction of the distance from "
                 "the map's origin. The map records it, and every pose in the map reports it in "
                 "its covariance. 0,0 for a generated sequence, whose calibration is exact");
  parser.SetDefaultText("rig-error", "a real rig's, measured on EuRoC MH_01: 0.0025,0.0026");
  parser.AddSwitch("level-body", &options.level_body,
                   "the rig's body frame (cam0's T_BS) is level, z up, as a ground robot's base "
                   "is: the map's up direction when the recording has no accelerometer");
  int max_features = 0;
  parser.AddFlag("max-features", &max_features, "corners per image");
  parser.SetDefaultText("max-features", "0: 600 at 320x240, more for larger images");
  parser.AddFlag("min-points", &options.min_points,
                 "refuse to write a map with fewer points, saying why");
  parser.AddFlag("check-frames", &options.check_frames,
                 "frames on which the rig is checked before the build (0: no check)");
  options.builder.threads = 0;
  parser.AddFlag("threads", &options.builder.threads,
                 "threads for features, stereo matching and decoding (the same map for any "
                 "count)");
  parser.SetDefaultText("threads", "0: every core");
  parser.AddSwitch("json", &json, "print the summary as JSON");
  if (!parser.Parse(args, std::cout)) return 0;
  if (!(options.builder.keyframes.translation_m > 0) ||
      !(options.builder.keyframes.rotation_deg > 0)) {
    throw UsageError("keyframe thresholds must be positive");
  }
  if (max_features < 0 || options.min_points < 0 || options.check_frames < 0) {
    throw UsageError("--max-features, --min-points and --check-frames must not be negative");
  }
  options.builder.loop_closure.enabled = loop_closure != 0;
  const GivenCorrection given = ParseGivenCorrection(known_correction, correction_map);
  const std::optional<RigError> given_rig_error = ParseRigError(rig_error);
  options.builder.disparity_calibration.known = given.correction;
  options.builder.disparity_calibration.enabled =
      disparity_calibration != 0 && !options.builder.disparity_calibration.known;
  CheckFlags(options.builder);  // --threads, the correction's range, what the checks above leave.
  server.ApplyEnvironment();
  if (server.server.empty() == out.empty()) {
    throw UsageError(
        "give --out MAP.db (build here) or --server ADDR --name NAME (the server "
        "builds it)");
  }
  if (!server.server.empty() && name.empty()) {
    throw UsageError("--server needs --name: the name the map is published under");
  }
  if (name.empty()) name = fs::path(out).stem().string();
  mapstore::CheckMapName(name);
  if (dataset_dir.empty() && cameras.empty()) throw UsageError("missing --dataset");
  if (!dataset_dir.empty() && !cameras.empty()) {
    throw UsageError("give --dataset DIR or two cameras (--camera L --camera R), not both");
  }
  if (!cameras.empty()) {
    if (server.server.empty()) throw UsageError("--camera maps over the link: give --server");
    if (cameras.size() != 2 || camera_yamls.size() != 2) {
      throw UsageError("--camera L --camera R with --camera-yaml L.yaml --camera-yaml R.yaml");
    }
  }
  const FrameRange range = ParseFrameRange(frames);
  std::optional<Dataset> dataset;
  if (!dataset_dir.empty()) {
    dataset = SelectFrames(ReadDataset(dataset_dir, ParseOptionalDatasetFormat(format)), range);
  }
  if (given.map_camera) {
    RequireCorrectionCamera(
        given, dataset ? dataset->left.camera : ReadSensorYaml(camera_yamls[0]).camera);
  }
  if (!server.server.empty()) {
    if (!trajectory.empty() || max_features > 0 || given_rig_error) {
      throw UsageError("--trajectory, --max-features and --rig-error are for builds here (--out)");
    }
    RemoteBuildOptions remote;
    remote.name = name;
    remote.robot_id = robot_id;
    remote.rate_hz = rate_hz;
    if (!(resume_s >= 0)) throw UsageError("--resume-s must not be negative");
    remote.resume_s = resume_s;
    remote.progress = ShowProgress() && !json;
    remote.json = json;
    remote.wire.set_replace(replace);
    remote.wire.set_extend(extend);
    remote.wire.set_features(features);
    remote.wire.set_keyframe_translation_m(options.builder.keyframes.translation_m);
    remote.wire.set_keyframe_rotation_deg(options.builder.keyframes.rotation_deg);
    remote.wire.set_loop_closure(loop_closure != 0);
    remote.wire.set_disparity_calibration(options.builder.disparity_calibration.enabled);
    if (const auto& known = options.builder.disparity_calibration.known) {
      proto::ToProto(*known, remote.wire.mutable_disparity_correction());
    }
    remote.wire.set_min_points(static_cast<uint32_t>(options.min_points));
    if (!cameras.empty()) {
      if (range.begin != 0 || range.step != 1) throw UsageError("with --camera, --frames is N");
      const int pairs = range.all() ? 0 : static_cast<int>(std::min<size_t>(range.end, 1 << 30));
      return RemoteMapBuildFromCameras(server, cameras, camera_yamls, pairs, remote);
    }
    return RemoteMapBuild(server, *dataset, remote);
  }
  options.builder.features = DefaultFeatureSettings(features);
  if (max_features > 0) {
    options.builder.features = WithMaxFeatures(options.builder.features, max_features);
    options.builder.scale_feature_count = false;
  }
  MapMetadata metadata{name, static_cast<int64_t>(std::time(nullptr)),
                       fs::absolute(dataset_dir).string(),
                       StrCat("visloc ", VislocVersion(), " map build"), ""};
  metadata.rig_error = given_rig_error;
  mapping::MapBuildStats stats;
  Trajectory frame_trajectory;
  const bool progress = ShowProgress() && !json;
  QuarterClock quarters;
  const Map map = mapping::BuildMap(*dataset, options, metadata, &stats, &frame_trajectory,
                                    [&](int done, int total, const std::string& status) {
                                      quarters.Frame(done, total);
                                      if (progress)
                                        std::fprintf(stderr, "\r\33[Kframe %d / %d: %s", done,
                                                     total, status.c_str());
                                    });
  if (progress) std::fprintf(stderr, "\r\33[K");
  mapstore::SaveMap(map, out);
  if (!trajectory.empty()) WriteTum(trajectory, frame_trajectory);
  if (json) {
    JsonWriter writer;
    writer.BeginObject()
        .Field("map", out)
        .Field("frames", stats.frames)
        .Field("keyframes", stats.keyframes)
        .Field("points", stats.points)
        .Field("observations", stats.observations)
        .Field("loop_closures", stats.loop_closures)
        .Field("loop_adjustments", stats.loop_adjustments)
        .Field("tracking_failures", stats.tracking_failures)
        .Field("reprojection_rmse_px", stats.reprojection_rmse_px)
        .Field("disparity_rmse_px", stats.disparity_rmse_px)
        .Field("disparity_offset_px", stats.disparity_correction.offset_px)
        .Field("right_camera_yaw_deg", stats.disparity_correction.yaw_deg())
        .Field("calibration_passes", stats.calibration_passes)
        .Field("visibility_fit_rmse", stats.visibility.final_rmse)
        .Field("up", stats.gravity);
    writer.Key("up_in_map");
    if (const auto& gravity = map.metadata.gravity) {
      writer.BeginArray();
      for (int i = 0; i < 3; ++i) writer.Value(gravity->up_in_map[i]);
      writer.EndArray();
    } else {
      writer.Null();
    }
    writer.Field("features_ms", stats.features_ms)
        .Field("tracking_ms", stats.tracking_ms)
        .Field("local_ba_ms", stats.local_ba_ms)
        .Field("loop_closure_ms", stats.loop_ms)
        .Field("global_ba_ms", stats.global_ba_ms)
        .Field("global_ba_pieces", static_cast<int64_t>(stats.global_ba_pieces))
        .Field("stereo_keypoints", stats.stereo_keypoints)
        .Field("stereo_searched", stats.stereo_searched)
        .Field("learning_ms", stats.learning_ms)
        .Field("total_s", stats.total_ms / 1000)
        .Field("fps", stats.frames / (stats.total_ms / 1000));
    // Whether the cost of a frame grows with the run (the end's adjustment excluded).
    writer.Key("quarter_frame_ms").BeginArray();
    for (const double ms : quarters.FrameMs()) writer.Value(ms);
    writer.EndArray().Field("peak_rss_mib", PeakResidentMib()).EndObject();
    std::cout << writer.str() << "\n";
    return 0;
  }
  std::printf("map %s -> %s\n", name.c_str(), out.c_str());
  std::printf("  %d frames, %d keyframes, %d points, %d observations (%.1f per point)\n",
              stats.frames, stats.keyframes, stats.points, stats.observations,
              stats.points ? static_cast<double>(stats.observations) / stats.points : 0.0);
  std::printf(
      "  loop closures %d (%d re-adjusting every keyframe), tracking failures %d,\n"
      "  reprojection RMSE %.3f px, disparity RMSE %.3f px, visibility fit RMSE %.3f (%d pairs)\n",
      stats.loop_closures, stats.loop_adjustments, stats.tracking_failures,
      stats.reprojection_rmse_px, stats.disparity_rmse_px, stats.visibility.final_rmse,
      stats.visibility.pairs);
  const std::string how = options.builder.disparity_calibration.known
                              ? std::string("given")
                              : StrCat("estimated over ", stats.calibration_passes, " adjustments");
  std::printf("  the rig's disparities: %.2f px offset, right camera turned %.3f deg (%s)\n",
              stats.disparity_correction.offset_px, stats.disparity_correction.yaw_deg(),
              how.c_str());
  std::printf("  up: %s\n", stats.gravity.c_str());
  std::printf(
      "  time: features %.1f s, tracking %.1f s, local BA %.1f s, loop closure %.1f s, global BA "
      "%.1f s, "
      "learning %.1f s; total %.1f s (%.1f frames/s)\n",
      stats.features_ms / 1000, stats.tracking_ms / 1000, stats.local_ba_ms / 1000,
      stats.loop_ms / 1000, stats.global_ba_ms / 1000, stats.learning_ms / 1000,
      stats.total_ms / 1000, stats.frames / (stats.total_ms / 1000));
  return 0;
}

int RunList(const Args& args) {
  std::string maps_dir;
  bool json = false;
  Connection server;
  ArgParser parser("visloc map list",
                   "Lists the maps in a maps folder or on a server, with broken ones and why.");
  parser.AddFlag("maps", &maps_dir, "maps folder");
  server.AddFlags(parser, /*server_required=*/false);
  parser.AddSwitch("json", &json, "print a JSON array");
  if (!parser.Parse(args, std::cout)) return 0;
  RequireOneOf(maps_dir, server);
  if (!server.server.empty()) return RemoteMapList(server, json);
  return PrintMapList(mapstore::MapDirectory(maps_dir).List(), "in " + maps_dir, json);
}

int RunDelete(const Args& args) {
  std::string name, maps_dir;
  Connection server;
  ArgParser parser("visloc map delete", "Deletes a map from a maps folder or a server.");
  parser.AddPositional("NAME", &name, "the map's name");
  parser.AddFlag("maps", &maps_dir, "maps folder");
  server.AddFlags(parser, /*server_required=*/false);
  bool force = false, json = false;
  parser.AddSwitch("force", &force,
                   "with --server: delete it although robots are localizing in it (they keep it "
                   "until their sessions end)");
  parser.AddSwitch("json", &json, "print one JSON object");
  if (!parser.Parse(args, std::cout)) return 0;
  RequireOneOf(maps_dir, server);
  if (!server.server.empty()) return RemoteMapDelete(server, name, force, json);
  mapstore::MapDirectory(maps_dir).Remove(name);
  return PrintOutcome(json, StrCat("deleted ", name), {{"deleted", name}, {"maps", maps_dir}});
}

int RunRename(const Args& args) {
  std::string from, to, maps_dir;
  ArgParser parser("visloc map rename",
                   "Renames a map in a maps folder or on a server (its file and its own name).");
  Connection server;
  parser.AddPositional("OLD", &from, "the current name");
  parser.AddPositional("NEW", &to, "the new name");
  parser.AddFlag("maps", &maps_dir, "maps folder");
  server.AddFlags(parser, /*server_required=*/false);
  bool json = false;
  parser.AddSwitch("json", &json, "print one JSON object");
  if (!parser.Parse(args, std::cout)) return 0;
  RequireOneOf(maps_dir, server);
  if (!server.server.empty()) return RemoteMapRename(server, from, to, json);
  mapstore::MapDirectory(maps_dir).Rename(from, to);
  return PrintOutcome(json, StrCat("renamed ", from, " -> ", to),
                      {{"renamed", from}, {"to", to}, {"maps", maps_dir}});
}

int RunUpload(const Args& args) {
  std::string path, name;
  Connection server;
  bool replace = false;
  ArgParser parser("visloc map upload",
                   "Uploads a map file to a server in checksummed chunks; the server publishes it "
                   "only once it is complete and verified.");
  parser.AddPositional("MAP", &path, "the map file");
  parser.AddFlag("name", &name, "name on the server (default: the map's own name)");
  server.AddFlags(parser);
  parser.AddSwitch("replace", &replace, "replace a map of that name");
  bool force = false, json = false;
  parser.AddSwitch("force", &force,
                   "with --replace: replace it although robots are localizing in it (running "
                   "sessions keep the old map, new ones get the new)");
  parser.AddSwitch("json", &json, "print one JSON object");
  if (!parser.Parse(args, std::cout)) return 0;
  if (force && !replace) throw UsageError("--force goes with --replace");
  server.ApplyEnvironment();
  return RemoteMapUpload(server, path, name, replace, force, json);
}

int RunDownload(const Args& args) {
  std::string name, out;
  Connection server;
  ArgParser parser("visloc map download", "Downloads a map from a server into a file.");
  parser.AddPositional("NAME", &name, "the map's name on the server");
  parser.AddFlag("out", &out, "map file to write", /*required=*/true);
  server.AddFlags(parser);
  bool json = false;
  parser.AddSwitch("json", &json, "print one JSON object");
  if (!parser.Parse(args, std::cout)) return 0;
  server.ApplyEnvironment();
  return RemoteMapDownload(server, name, out, json);
}

}  // namespace

int RunMap(const Args& args) {
  static const std::vector<Subcommand> kVerbs = {
      {"build", "build a map from a stereo sequence", RunBuild},
      {"info", "counts, extent, camera, features, size and schema", RunInfo},
      {"verify", "check a map file; exit 0 when sound", RunVerify},
      {"export", "keyframe poses (TUM) and a point cloud (PLY)", RunExport},
      {"merge", "two maps of overlapping places into one, in the first one's frame", RunMapMerge},
      {"extend", "add a new stereo session to a map, in the map's frame", RunMapExtend},
      {"update", "the place changed: remove what is gone, add what is new", RunMapUpdate},
      {"align", "tie a map to its site's frame (surveyed spots, a reference trajectory)",
       RunMapAlign},
      {"localizability", "where a robot will localize well, looking which way, from the map alone",
       RunMapLocalizability},
      {"list", "the maps in a maps folder or on a server", RunList},
      {"delete", "delete a map from a maps folder or a server", RunDelete},
      {"rename", "rename a map in a maps folder or on a server", RunRename},
      {"upload", "upload a map file to a server", RunUpload},
      {"download", "download a map from a server", RunDownload},
  };
  return DispatchSubcommand("visloc map VERB [options]", "Manage map files. Verbs:", kVerbs, args);
}

}  // namespace visloc::cli
