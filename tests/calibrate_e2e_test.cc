// End-to-end calibration with `visloc calibrate`:
//  - on real images Debian ships (opencv-doc's 13 stereo chessboard pairs, 9x6 inner corners),
//    against OpenCV's own stereo_calib sample run on the same images (built from Debian's
//    source by tests/CMakeLists.txt): the same focal lengths and baseline within 1 %;
//  - on chessboards rendered through a fisheye rig of known parameters: the sensor.yaml files it
//    writes are read as they are by dataset check and map build, and a map built with them is
//    as accurate as one built with the true calibration.

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include <opencv2/core.hpp>

#include "core/util/temp_dir.h"
#include "tests/support/e2e.h"
#include "tests/support/process.h"

namespace visloc {
namespace {

using ::testing::HasSubstr;
using testing::JsonNumber;
using testing::ProcessResult;
using testing::RunProcess;
using testing::Visloc;
namespace fs = std::filesystem;

const std::string kSamples = VISLOC_OPENCV_SAMPLES;

TEST(CalibrateE2eTest, OpenCvStereoBoardsGiveTheFocalLengthsAndBaselineOfOpenCvsSample) {
#ifndef VISLOC_OPENCV_STEREO_CALIB
  GTEST_SKIP() << "opencv-doc is not installed: no sample images and no stereo_calib sample";
#else
  const std::string data = kSamples + "/data";
  TempDir dir("visloc_calibrate");
  std::vector<std::string> left, right;
  std::string list = "<?xml version=\"1.0\"?>\n<opencv_storage>\n<imagelist>\n";
  for (int i : {1, 2, 3, 4, 5, 6, 7, 8, 9, 11, 12, 13, 14}) {
    char name[32];
    std::snprintf(name, sizeof(name), "%02d.jpg", i);
    left.push_back(data + "/left" + name);
    right.push_back(data + "/right" + name);
    list += "\"" + left.back() + "\"\n\"" + right.back() + "\"\n";
  }
  std::ofstream(dir.File("list.xml")) << list << "</imagelist>\n</opencv_storage>\n";
  // OpenCV's sample writes intrinsics.yml and extrinsics.yml where it runs.
  const fs::path cwd = fs::current_path();
  fs::current_path(dir.path());
  const ProcessResult sample = RunProcess({VISLOC_OPENCV_STEREO_CALIB, "-w=9", "-h=6", "-s=1.0",
                                           "-nr", dir.File("list.xml")});
  fs::current_path(cwd);
  ASSERT_EQ(sample.exit_code, 0) << sample.out << sample.err;
  cv::FileStorage intrinsics(dir.File("intrinsics.yml"), cv::FileStorage::READ);
  cv::FileStorage extrinsics(dir.File("extrinsics.yml"), cv::FileStorage::READ);
  cv::Mat m1, m2, t;
  intrinsics["M1"] >> m1;
  intrinsics["M2"] >> m2;
  extrinsics["T"] >> t;
  ASSERT_FALSE(m1.empty() || m2.empty() || t.empty());

  std::vector<std::string> args = {"calibrate", "--board", "9x6", "--square", "1.0", "--out",
                                   dir.File("out"), "--json", "--left"};
  args.insert(args.end(), left.begin(), left.end());
  args.push_back("--right");
  args.insert(args.end(), right.begin(), right.end());
  const ProcessResult ours = Visloc(args);
  ASSERT_EQ(ours.exit_code, 0) << ours.err;
  const double baseline = JsonNumber(ours.out, "baseline_m");
  const double sample_baseline = cv::norm(t);
  std::printf("fx %.2f / %.2f (sample %.2f / %.2f), fy %.2f / %.2f (sample %.2f), baseline %.4f "
              "squares (sample %.4f), RMS %.3f / %.3f px, pair %.3f px\n",
              JsonNumber(ours.out, "left", "fx"), JsonNumber(ours.out, "right", "fx"),
              m1.at<double>(0, 0), m2.at<double>(0, 0), JsonNumber(ours.out, "left", "fy"),
              JsonNumber(ours.out, "right", "fy"), m1.at<double>(1, 1), baseline,
              sample_baseline, JsonNumber(ours.out, "left", "rms_px"),
              JsonNumber(ours.out, "right", "rms_px"), JsonNumber(ours.out, "stereo_rms_px"));
  // The sample fits one focal length to both cameras (CALIB_SAME_FOCAL_LENGTH) at the aspect
  // ratio of its initial guess, with a rational lens model; visloc fits fx and fy per camera
  // with k1 k2 p1 p2. The rig's focal length (the mean over both cameras of sqrt(fx fy)) is
  // the quantity both estimate; each camera's own stays within 1.5 % of the sample's.
  const auto focal = [&](const char* camera) {
    return std::sqrt(JsonNumber(ours.out, camera, "fx") * JsonNumber(ours.out, camera, "fy"));
  };
  const double sample_focal = std::sqrt(m1.at<double>(0, 0) * m1.at<double>(1, 1));
  const double rig_focal = 0.5 * (focal("left") + focal("right"));
  std::printf("focal length: visloc %.2f (left %.2f, right %.2f), sample %.2f: %+.2f %%\n",
              rig_focal, focal("left"), focal("right"), sample_focal,
              100 * (rig_focal / sample_focal - 1));
  EXPECT_NEAR(rig_focal, sample_focal, 0.01 * sample_focal);
  EXPECT_NEAR(focal("left"), sample_focal, 0.015 * sample_focal);
  EXPECT_NEAR(focal("right"), sample_focal, 0.015 * sample_focal);
  EXPECT_NEAR(baseline, sample_baseline, 0.01 * sample_baseline);
  EXPECT_LT(JsonNumber(ours.out, "stereo_rms_px"), 0.5);
  EXPECT_TRUE(fs::exists(dir.File("out/cam0/sensor.yaml")));
  EXPECT_TRUE(fs::exists(dir.File("out/cam1/sensor.yaml")));
#endif
}

TEST(CalibrateE2eTest, ACalibratedFisheyeRigChecksAndMapsAsItsTrueCalibrationDoes) {
  TempDir dir("visloc_calibrate");
  const std::vector<std::string> rig = {"--resolution", "480x360", "--lens", "fisheye",
                                        "--distortion", "--realistic"};
  std::vector<std::string> board = {"sim", "--out", dir.File("board"), "--board", "9x6",
                                    "--square", "0.04", "--views", "25"};
  board.insert(board.end(), rig.begin(), rig.end());
  ASSERT_EQ(Visloc(board).exit_code, 0);
  std::vector<std::string> calibrate = {"calibrate", "--board", "9x6", "--square", "0.04",
                                        "--model", "equidistant", "--out", dir.File("est"),
                                        "--json", "--left"};
  for (const auto& entry : fs::directory_iterator(dir.File("board/left")))
    calibrate.push_back(entry.path().string());
  std::sort(calibrate.begin() + 11, calibrate.end());
  calibrate.push_back("--right");
  const size_t right_begin = calibrate.size();
  for (const auto& entry : fs::directory_iterator(dir.File("board/right")))
    calibrate.push_back(entry.path().string());
  std::sort(calibrate.begin() + right_begin, calibrate.end());
  const ProcessResult calibrated = Visloc(calibrate);
  ASSERT_EQ(calibrated.exit_code, 0) << calibrated.err;
  EXPECT_THAT(calibrated.out, HasSubstr("\"model\":\"equidistant\""));
  EXPECT_NEAR(JsonNumber(calibrated.out, "baseline_m"), 0.144, 0.002);

  // The same rig films a mapping run; its sensor files are replaced by the calibration's.
  std::vector<std::string> sequence = {"sim", "--out", dir.File("seq"), "--sequence",
                                       "map_square", "--frames", "60", "--no-contact-sheet"};
  sequence.insert(sequence.end(), rig.begin(), rig.end());
  ASSERT_EQ(Visloc(sequence).exit_code, 0);
  const std::string mav0 = dir.File("seq/map_square/mav0");
  for (const char* cam : {"cam0", "cam1"}) {
    fs::copy_file(dir.File(std::string("est/") + cam + "/sensor.yaml"),
                  mav0 + "/" + cam + "/sensor.yaml", fs::copy_options::overwrite_existing);
  }
  const ProcessResult check = Visloc({"dataset", "check", dir.File("seq/map_square"), "--json"});
  ASSERT_EQ(check.exit_code, 0) << check.out << check.err;
  EXPECT_LT(JsonNumber(check.out, "row_difference_median_px"), 0.3);
  const ProcessResult build =
      Visloc({"map", "build", "--dataset", dir.File("seq/map_square"), "--out",
              dir.File("map.db"), "--trajectory", dir.File("frames.tum"), "--json"});
  ASSERT_EQ(build.exit_code, 0) << build.err;
  EXPECT_EQ(JsonNumber(build.out, "tracking_failures"), 0);
  const ProcessResult eval =
      Visloc({"eval", "--gt", dir.File("seq/map_square/groundtruth_map.tum"), "--est",
              dir.File("frames.tum"), "--json"});
  ASSERT_EQ(eval.exit_code, 0) << eval.err;
  std::printf("mapping with the calibration: %.0f points, frames within %.2f cm (max %.2f cm)\n",
              JsonNumber(build.out, "points"), 100 * JsonNumber(eval.out, "translation_m", "rmse"),
              100 * JsonNumber(eval.out, "translation_m", "max"));
  EXPECT_LT(JsonNumber(eval.out, "translation_m", "max"), 0.03);
}

TEST(CalibrateE2eTest, BadInputIsRefusedClearly) {
  TempDir dir("visloc_calibrate");
  const ProcessResult board = Visloc({"calibrate", "--left", "a.png", "--board", "9x9",
                                      "--square", "0.04", "--out", dir.path()});
  EXPECT_EQ(board.exit_code, 2);
  EXPECT_THAT(board.err, HasSubstr("--board wants COLSxROWS inner corners"));
  const ProcessResult missing = Visloc({"calibrate", "--left", dir.File("nope.png"), "--board",
                                        "9x6", "--square", "0.04", "--out", dir.path()});
  EXPECT_EQ(missing.exit_code, 1);
  EXPECT_THAT(missing.err, HasSubstr("nope.png: no such image"));
  const ProcessResult model = Visloc({"calibrate", "--left", "a.png", "--board", "9x6",
                                      "--square", "0.04", "--model", "kb8", "--out", dir.path()});
  EXPECT_EQ(model.exit_code, 1);
  EXPECT_THAT(model.err, HasSubstr("unknown lens model 'kb8'"));
}

}  // namespace
}  // namespace visloc
