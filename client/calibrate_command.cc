// `visloc calibrate`: a camera or a stereo pair from chessboard views, written as EuRoC
// sensor.yaml files that dataset check, map build and stream read as they are
// (core/calibration/calibration.h).

#include <cstdio>
#include <filesystem>
#include <iostream>

#include "client/commands.h"
#include "core/calibration/calibration.h"
#include "core/util/args.h"
#include "core/util/check.h"
#include "core/util/json.h"
#include "core/util/strings.h"
#include "dataset/euroc.h"

namespace visloc::cli {
namespace fs = std::filesystem;
namespace {

// "9x6" -> 9, 6.
void ParseBoard(const std::string& text, ChessboardSpec* board) {
  const auto corners = ParseDimensions(text, 3, 100);
  if (!corners || corners->first == corners->second) {
    throw UsageError(
        StrCat("--board wants COLSxROWS inner corners, 3 to 100 each and different "
               "(e.g. 9x6), got '",
               text, "'"));
  }
  std::tie(board->cols, board->rows) = *corners;
}

std::vector<cv::Mat> LoadImages(const std::vector<std::string>& paths) {
  std::vector<cv::Mat> images;
  for (const std::string& path : paths) images.push_back(LoadGreyImage(path, 0, 0));
  return images;
}

void WriteCamera(JsonWriter& json, const std::string& key, const CameraCalibration& c) {
  const auto names = LensCoefficientNames(c.camera.lens().model);
  json.Key(key)
      .BeginObject()
      .Field("fx", c.camera.fx())
      .Field("fy", c.camera.fy())
      .Field("cx", c.camera.cx())
      .Field("cy", c.camera.cy());
  for (int i = 0; i < 4; ++i) json.Field(names[i], c.camera.lens().coefficients[i]);
  json.Field("rms_px", c.rms_px).Field("coverage", c.coverage).EndObject();
}

std::string ToJson(const CalibrationResult& r, const std::string& out,
                   const std::vector<std::string>& left_paths) {
  JsonWriter json;
  json.BeginObject()
      .Field("out", out)
      .Field("model", LensModelName(r.left.camera.lens().model))
      .Field("views", static_cast<int>(r.views_used.size()));
  WriteCamera(json, "left", r.left);
  if (r.right) {
    WriteCamera(json, "right", *r.right);
    const Eigen::Vector3d& t = r.right_from_left.translation;
    json.Field("baseline_m", t.norm())
        .Key("right_from_left")
        .BeginObject()
        .Field("x", t.x())
        .Field("y", t.y())
        .Field("z", t.z())
        .Field("rotation_deg", RotationAngleDeg(r.right_from_left.rotation))
        .EndObject()
        .Field("stereo_rms_px", r.stereo_rms_px);
  }
  json.Key("board_not_found").BeginArray();
  for (int i : r.board_not_found) json.Value(left_paths[i]);
  json.EndArray().Key("warnings").BeginArray();
  for (const std::string& w : r.warnings) json.Value(w);
  json.EndArray().EndObject();
  return json.str();
}

void PrintHuman(const CalibrationResult& r, const std::string& out,
                const std::vector<std::string>& left_paths) {
  std::printf("%zu views with the board (%zu without)\n", r.views_used.size(),
              r.board_not_found.size());
  std::printf("left:  %s\n       RMS %.3f px, corners in %.0f%% of the image\n",
              ToString(r.left.camera).c_str(), r.left.rms_px, 100 * r.left.coverage);
  if (r.right) {
    std::printf("right: %s\n       RMS %.3f px, corners in %.0f%% of the image\n",
                ToString(r.right->camera).c_str(), r.right->rms_px, 100 * r.right->coverage);
    const Eigen::Vector3d& t = r.right_from_left.translation;
    std::printf(
        "pair:  baseline %.4f m, right_from_left t (%.4f, %.4f, %.4f) m, turned %.3f "
        "deg; RMS %.3f px\n",
        t.norm(), t.x(), t.y(), t.z(), RotationAngleDeg(r.right_from_left.rotation),
        r.stereo_rms_px);
  }
  for (int i : r.board_not_found) {
    std::printf("board not found: %s\n", left_paths[i].c_str());
  }
  for (const std::string& w : r.warnings) std::printf("warning: %s\n", w.c_str());
  std::printf("written: %s/cam0/sensor.yaml%s\n", out.c_str(),
              r.right ? StrCat(", ", out, "/cam1/sensor.yaml").c_str() : "");
}

}  // namespace

int RunCalibrate(const Args& args) {
  std::vector<std::string> left_paths, right_paths;
  std::string board_text, model = "pinhole", out;
  CalibrationOptions options;
  options.board.square_m = 0;
  bool json = false;
  ArgParser parser("visloc calibrate",
                   "Calibrates a camera (--left only) or a stereo pair (--left and --right, taken "
                   "together) from views of a chessboard: intrinsics and lens coefficients per "
                   "camera and the right camera's pose, written as EuRoC sensor.yaml files "
                   "(OUT/cam0, OUT/cam1; T_BS with the left camera as the body) that dataset "
                   "check, map build and stream read as they are. Reports the RMS reprojection "
                   "error per camera and for the pair, the images where the board was not found, "
                   "and warns when the calibration is weak.");
  parser.AddList("left", &left_paths, "left (or only) camera's images", /*required=*/true);
  parser.AddList("right", &right_paths, "right camera's images, in the same order");
  parser.AddFlag("board", &board_text, "inner corners COLSxROWS, e.g. 9x6", /*required=*/true);
  parser.AddFlag("square", &options.board.square_m, "square side in metres", /*required=*/true);
  parser.AddFlag("model", &model,
                 "pinhole (radial-tangential lens: k1 k2 p1 p2) or equidistant (fisheye: k1..k4)");
  parser.AddFlag("out", &out, "folder for cam0/sensor.yaml (and cam1/)", /*required=*/true);
  parser.AddSwitch("json", &json, "print one JSON object");
  if (!parser.Parse(args, std::cout)) return 0;
  ParseBoard(board_text, &options.board);
  if (!(options.board.square_m > 0) || options.board.square_m > 10) {
    throw UsageError("--square wants the square side in metres (e.g. 0.025)");
  }
  options.model = model == "pinhole" ? LensModel::kRadialTangential : ParseLensModel(model);
  const CalibrationResult result =
      Calibrate(LoadImages(left_paths), LoadImages(right_paths), options);
  CameraInfo left;
  left.camera = result.left.camera;  // The body frame is the left camera's.
  fs::create_directories(out + "/cam0");
  WriteSensorYaml(out + "/cam0/sensor.yaml", left, "left camera (visloc calibrate)");
  if (result.right) {
    CameraInfo right;
    right.camera = result.right->camera;
    right.body_from_cam = result.right_from_left.Inverse();
    fs::create_directories(out + "/cam1");
    WriteSensorYaml(out + "/cam1/sensor.yaml", right, "right camera (visloc calibrate)");
  }
  if (json) {
    std::cout << ToJson(result, out, left_paths) << "\n";
  } else {
    PrintHuman(result, out, left_paths);
  }
  return 0;
}

}  // namespace visloc::cli
