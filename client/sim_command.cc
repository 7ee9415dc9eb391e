#include <cmath>
#include <cstdio>
#include <iostream>

#include "client/commands.h"
#include "core/util/args.h"
#include "core/util/check.h"
#include "core/util/json.h"
#include "core/util/strings.h"
#include "core/util/timer.h"
#include "sim/board_views.h"
#include "sim/generate.h"

namespace visloc::cli {
namespace {

// "320x240" -> (320, 240).
void ParseResolution(const std::string& text, int* width, int* height) {
  const auto size = ParseDimensions(text, 16, 4096);
  if (!size) {
    throw UsageError("--resolution expects WIDTHxHEIGHT between 16 and 4096, got '" + text + "'");
  }
  std::tie(*width, *height) = *size;
}

std::vector<std::string> SelectSequences(const std::string& selection) {
  if (selection == "all") return sim::SequenceNames();
  std::vector<std::string> names;
  for (const std::string& name : Split(selection, ',')) {
    sim::MakeSequenceSpec(name, 1);  // Throws with the list of known names.
    names.push_back(name);
  }
  return names;
}

}  // namespace

int RunSim(const Args& args) {
  std::string out_dir, sequences = "all", resolution = "320x240", format = "euroc";
  sim::GenerateOptions options;
  int64_t seed = 1;
  bool list = false, no_sheet = false, json = false;
  ArgParser parser(
      "visloc sim",
      "Renders synthetic stereo sequences of an indoor room (and, `drive`, a street seen from "
      "a car with KITTI's rig) with exact ground truth, IMU and walking-planner odometry "
      "(EuRoC layout by default). Each sequence folder also holds groundtruth_map.tum (left "
      "camera in the map frame, i.e. the first frame of map_square; of `drive`, its own first "
      "frame), odometry_map.tum (dead reckoning from the true start pose), "
      "sequence.json and contact_sheet.png.");
  parser.AddFlag("out", &out_dir, "output folder (one sub-folder per sequence)");
  parser.AddFlag("sequence", &sequences, "'all' or a comma-separated list of names (see --list)");
  parser.AddFlag("resolution", &resolution, "image size WIDTHxHEIGHT");
  parser.AddFlag("fps", &options.rig.fps, "frame rate");
  parser.AddFlag("frames", &options.max_frames, "stop after this many frames (0: whole sequence)");
  parser.AddFlag("seed", &seed, "seed for textures, noise and odometry drift");
  parser.AddFlag("supersample", &options.supersample, "anti-aliasing samples per pixel side (1-8)");
  parser.AddFlag("threads", &options.render_threads,
                 "1, or 2 to render a frame's two views at once (the same images, faster)");
  parser.AddFlag("format", &format, "dataset layout: euroc or kitti");
  parser.AddSwitch("distortion", &options.rig.distortion,
                   "lens distortion (radial-tangential; with --lens fisheye, k1..k4)");
  std::string lens = "pinhole";
  parser.AddFlag("lens", &lens, "pinhole or fisheye (equidistant)");
  parser.AddFlag("fisheye-fov", &options.rig.fisheye_fov_deg,
                 "the fisheye's field of view across the image diagonal, degrees (below 180)");
  bool realistic = false;
  parser.AddSwitch("realistic", &realistic,
                   "what real cameras do: two cameras with their own intrinsics, a slightly "
                   "turned rig, auto-exposure changes, vignetting and motion blur");
  parser.AddFlag("right-yaw-error", &options.rig.right_yaw_error_deg,
                 "the right camera is really turned by this many degrees about its y axis against "
                 "its written calibration (a stereo calibration's residual error)");
  parser.AddFlag("camera-pitch", &options.rig.camera_pitch_deg,
                 "the stereo pair is mounted pitched down by this many degrees (the map frame, its "
                 "first left camera's, then is not level)");
  parser.AddFlag("camera-roll", &options.rig.camera_roll_deg,
                 "the stereo pair is mounted rolled right by this many degrees");
  std::string rig_layout = "stereo";
  parser.AddFlag(
      "rig", &rig_layout,
      "cameras on the head: stereo (the pair), front-back (and a rear camera, cam2) or "
      "four (rear, left and right: cam2, cam3, cam4); a cover hides the front pair only");
  std::string board;
  sim::BoardViewOptions board_views;
  parser.AddFlag("board", &board,
                 "instead of sequences, chessboard views for calibration: inner corners "
                 "COLSxROWS (left/, right/ and the true truth/cam0|cam1/sensor.yaml)");
  parser.AddFlag("square", &board_views.square_m, "the chessboard's square side, metres");
  parser.AddFlag("views", &board_views.views, "chessboard views to render");
  parser.AddSwitch("no-contact-sheet", &no_sheet, "do not write contact_sheet.png");
  parser.AddSwitch("list", &list, "list the sequences and exit");
  parser.AddSwitch("json", &json, "print a JSON summary");
  if (!parser.Parse(args, std::cout)) return 0;
  if (list) {
    for (const std::string& name : sim::SequenceNames()) {
      std::printf("%-14s %s\n", name.c_str(), sim::MakeSequenceSpec(name, 1).description.c_str());
    }
    for (const std::string& name : sim::LongSequenceNames()) {
      std::printf("%-14s %s (by name only, not in \"all\")\n", name.c_str(),
                  sim::MakeSequenceSpec(name, 1).description.c_str());
    }
    return 0;
  }
  if (out_dir.empty()) throw UsageError("missing --out");
  ParseResolution(resolution, &options.rig.width, &options.rig.height);
  if (options.rig.fps <= 0 || options.rig.fps > 200) throw UsageError("--fps must be in (0, 200]");
  if (options.max_frames < 0) throw UsageError("--frames must not be negative");
  if (options.render_threads < 1 || options.render_threads > 2)
    throw UsageError("--threads must be 1 or 2");
  if (options.supersample < 1 || options.supersample > 8)
    throw UsageError("--supersample must be 1-8");
  if (seed < 0) throw UsageError("--seed must not be negative");
  options.seed = static_cast<uint64_t>(seed);
  options.format = ParseDatasetFormat(format);
  if (lens != "pinhole" && lens != "fisheye") throw UsageError("--lens must be pinhole or fisheye");
  options.rig.fisheye = lens == "fisheye";
  options.rig.layout = sim::ParseRigLayout(rig_layout);
  if (!(options.rig.fisheye_fov_deg >= 90 && options.rig.fisheye_fov_deg < 180)) {
    throw UsageError("--fisheye-fov must be in [90, 180)");
  }
  if (!(std::abs(options.rig.camera_pitch_deg) <= 45.0) ||
      !(std::abs(options.rig.camera_roll_deg) <= 45.0)) {
    throw UsageError("--camera-pitch and --camera-roll must be within +-45 degrees");
  }
  if (!(std::abs(options.rig.right_yaw_error_deg) <= 5.0)) {
    throw UsageError("--right-yaw-error must be within +-5 degrees");
  }
  if (realistic) {
    options.rig.imperfect = true;
    options.effects = sim::CameraEffects{};
  }
  if (options.format == DatasetFormat::kKitti) {
    const char* flag = options.rig.distortion ? "--distortion"
                       : options.rig.fisheye  ? "--lens fisheye"
                       : realistic            ? "--realistic"
                                              : nullptr;
    if (flag)
      throw UsageError(StrCat("KITTI sequences are rectified: ", flag, " needs --format euroc"));
  }
  options.contact_sheet = !no_sheet;
  if (!board.empty()) {
    const auto corners = ParseDimensions(board, 3, 100);
    if (!corners || corners->first == corners->second) {
      throw UsageError("--board wants COLSxROWS inner corners, 3 to 100 each and different");
    }
    std::tie(board_views.cols, board_views.rows) = *corners;
    if (!(board_views.square_m > 0) || board_views.views < 1) {
      throw UsageError("--square must be positive and --views at least 1");
    }
    board_views.seed = options.seed;
    board_views.supersample = options.supersample;
    const sim::BoardViewStats stats = sim::GenerateBoardViews(options.rig, board_views, out_dir);
    std::printf("%d chessboard views (%d poses drawn) -> %s/left, %s/right, %s/truth\n",
                stats.views, stats.attempts, out_dir.c_str(), out_dir.c_str(), out_dir.c_str());
    return 0;
  }
  const std::vector<std::string> names = SelectSequences(sequences);

  sim::SequenceGenerator generator(options);
  JsonWriter summary;
  summary.BeginArray();
  Timer total;
  for (const std::string& name : names) {
    Timer timer;
    const bool progress = ShowProgress() && !json;
    const sim::GenerateStats stats = generator.Generate(name, out_dir, [&](int done, int all) {
      if (progress && (done % 10 == 0 || done == all)) {
        std::fprintf(stderr, "\r%-14s frame %4d / %4d", name.c_str(), done, all);
      }
    });
    if (progress) std::fprintf(stderr, "\r%60s\r", "");
    const double seconds = timer.ElapsedS();
    if (json) {
      summary.BeginObject()
          .Field("name", stats.name)
          .Field("dir", stats.dir)
          .Field("frames", stats.frames)
          .Field("covered_frames", stats.covered_frames)
          .Field("duration_s", stats.duration_s)
          .Field("path_length_m", stats.path_length_m)
          .Field("render_ms_per_frame", stats.render_ms_per_frame)
          .Field("seconds", seconds)
          .EndObject();
    } else {
      std::printf(
          "%-14s %4d frames %6.1f s of walk %5.2f m  rendered in %5.1f s (%5.1f ms/stereo frame)  "
          "-> %s\n",
          name.c_str(), stats.frames, stats.duration_s, stats.path_length_m, seconds,
          stats.render_ms_per_frame, stats.dir.c_str());
    }
  }
  summary.EndArray();
  if (json) {
    std::cout << summary.str() << "\n";
  } else {
    std::printf("%zu sequences in %.1f s\n", names.size(), total.ElapsedS());
  }
  return 0;
}

}  // namespace visloc::cli
