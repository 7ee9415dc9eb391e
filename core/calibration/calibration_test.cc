#include "core/calibration/calibration.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>

#include <opencv2/core/utility.hpp>

#include "core/image/image_codec.h"
#include "core/util/check.h"
#include "core/util/temp_dir.h"
#include "dataset/euroc.h"
#include "sim/board_views.h"

namespace visloc {
namespace {

// OpenCV's own thread pool, which calibration and the renderer start, crashes LeakSanitizer's
// exit-time scan (see RunOpenCvOnCallingThread): the tests run OpenCV on the calling thread, as
// the visloc binary does.
class OpenCvOnCallingThread : public ::testing::Environment {
 public:
  void SetUp() override { cv::setNumThreads(1); }
};
const ::testing::Environment* const kOpenCvOnCallingThread =
    ::testing::AddGlobalTestEnvironment(new OpenCvOnCallingThread);

// The largest distance (pixels) between where the two cameras put the same rays, at every
// corner the views saw: lens coefficients trade off against each other, the mapping they make
// must agree (beyond what the views saw, any calibration is extrapolation).
double ModelDifferencePx(const Camera& truth, const Camera& estimate,
                         const std::vector<cv::Mat>& images) {
  double worst = 0;
  for (const cv::Mat& image : images) {
    for (const cv::Point2f& corner : FindChessboard(image, ChessboardSpec{})) {
      const Eigen::Vector2d seen(corner.x, corner.y);
      const Eigen::Vector3d ray = truth.Unproject(seen);
      Eigen::Vector2d pixel;
      if (!ray.allFinite() || !estimate.Project(ray, &pixel)) return 1e9;
      worst = std::max(worst, (pixel - seen).norm());
    }
  }
  return worst;
}

struct Rendered {
  std::vector<cv::Mat> left, right;
  CameraInfo left_truth, right_truth;
};

Rendered Render(const sim::RigOptions& rig, int views) {
  TempDir dir;
  sim::BoardViewOptions options;
  options.views = views;
  sim::GenerateBoardViews(rig, options, dir.path());
  Rendered r;
  for (int i = 0; i < views; ++i) {
    char name[16];
    std::snprintf(name, sizeof(name), "/%03d.png", i);
    std::string error;
    r.left.push_back(image::ReadGrey(dir.path() + "/left" + name, &error));
    r.right.push_back(image::ReadGrey(dir.path() + "/right" + name, &error));
  }
  r.left_truth = ReadSensorYaml(dir.path() + "/truth/cam0/sensor.yaml");
  r.right_truth = ReadSensorYaml(dir.path() + "/truth/cam1/sensor.yaml");
  return r;
}

void ExpectRigComesBack(const sim::RigOptions& rig, LensModel model) {
  const Rendered r = Render(rig, 25);
  CalibrationOptions options;
  options.board.square_m = 0.04;
  options.model = model;
  const CalibrationResult result = Calibrate(r.left, r.right, options);
  ASSERT_TRUE(result.right.has_value());
  const Camera& left = result.left.camera;
  const Camera& right = result.right->camera;
  const Rigid3d truth_right_from_left = r.right_truth.body_from_cam.Inverse();
  std::printf("left fx %.2f (true %.2f), RMS %.3f px, model within %.3f px; right within %.3f "
              "px; baseline %.2f mm (true %.2f), pair RMS %.3f px\n",
              left.fx(), r.left_truth.camera.fx(), result.left.rms_px,
              ModelDifferencePx(r.left_truth.camera, left, r.left),
              ModelDifferencePx(r.right_truth.camera, right, r.right),
              1e3 * result.right_from_left.translation.norm(),
              1e3 * truth_right_from_left.translation.norm(), result.stereo_rms_px);
  EXPECT_EQ(left.lens().model, model);
  EXPECT_NEAR(left.fx(), r.left_truth.camera.fx(), 0.005 * left.fx());
  EXPECT_NEAR(left.cx(), r.left_truth.camera.cx(), 1.0);
  // 25 views pin the principal point to a pixel or so (40: a third of a pixel).
  EXPECT_LT(ModelDifferencePx(r.left_truth.camera, left, r.left), 1.0);
  EXPECT_LT(ModelDifferencePx(r.right_truth.camera, right, r.right), 1.0);
  EXPECT_LT((result.right_from_left.translation - truth_right_from_left.translation).norm(), 0.002);
  EXPECT_LT(RotationAngleDeg(result.right_from_left.rotation.conjugate() *
                             truth_right_from_left.rotation),
            0.3);
  EXPECT_LT(result.left.rms_px, 0.3);
  EXPECT_LT(result.stereo_rms_px, 0.3);
  EXPECT_TRUE(result.board_not_found.empty());
}

sim::RigOptions Rig480() {
  sim::RigOptions rig;
  rig.width = 480;
  rig.height = 360;
  return rig;
}

TEST(CalibrationTest, ADistortedImperfectPinholeRigComesBack) {
  sim::RigOptions rig = Rig480();
  rig.distortion = true;
  rig.imperfect = true;
  ExpectRigComesBack(rig, LensModel::kRadialTangential);
}

TEST(CalibrationTest, AFisheyeRigComesBack) {
  sim::RigOptions rig = Rig480();
  rig.fisheye = true;
  rig.distortion = true;
  rig.imperfect = true;
  ExpectRigComesBack(rig, LensModel::kEquidistant);
}

TEST(CalibrationTest, TooFewBoardsAreRefusedAndFewViewsWarned) {
  const Rendered r = Render(Rig480(), 4);
  CalibrationOptions options;
  options.board.square_m = 0.04;
  const CalibrationResult mono = Calibrate(r.left, {}, options);
  EXPECT_FALSE(mono.right.has_value());
  EXPECT_THAT(mono.warnings, ::testing::Contains(::testing::HasSubstr("only 4 views")));
  // Views without the board: refused, saying what was looked for. (Blank views: the sector
  // detector's exhaustive search of rendered views for a board that is not there leaves OpenCV
  // in a state that crashes LeakSanitizer's exit-time scan, in this test process only.)
  const cv::Mat blank(r.left[0].size(), CV_8UC1, cv::Scalar(128));
  try {
    Calibrate({blank, blank, r.left[0]}, {blank, blank, r.right[0]}, options);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("9x6 board was found in 1 of 3 image pairs"));
  }
  // A blank image among the views is reported, not fatal.
  std::vector<cv::Mat> with_blank = r.left;
  with_blank.push_back(blank);
  EXPECT_EQ(Calibrate(with_blank, {}, options).board_not_found, std::vector<int>{4});
  EXPECT_THROW(Calibrate(r.left, {r.right[0]}, options), InputError);  // Not pairs.
}

}  // namespace
}  // namespace visloc
