// End-to-end on rigs that behave like real ones (the camera_models_data fixture,
// tests/support/make_camera_models_data.sh): two cameras with their own intrinsics and lenses,
// turned slightly against each other, auto-exposure changes, vignetting and motion blur; once
// with radial-tangential lenses and once with equidistant fisheyes seeing 170 degrees. Each
// must check, map, and localize with the accuracy targets of the ideal pinhole rig (issue 5:
// >= 99 % of the offset square, median <= 2 cm and <= 0.3 deg), in-process and, for the
// fisheye, through the real server (the lens crosses the wire in CameraModel.lens_model).

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>

#include "core/util/temp_dir.h"
#include "tests/support/e2e.h"
#include "tests/support/process.h"

namespace visloc {
namespace {

using ::testing::HasSubstr;
using testing::JsonNumber;
using testing::ProcessResult;
using testing::ServerProcess;
using testing::Visloc;

const std::string kData = VISLOC_CAMERA_MODELS_DATA;

class CameraModelsE2eTest : public ::testing::TestWithParam<std::string> {
 protected:
  std::string Rig() const { return kData + "/" + GetParam(); }
  TempDir dir_{"visloc_camera_models"};
};

// localized fraction, median error (m) and median rotation error (deg) of a trajectory file.
void ExpectTargets(const std::string& label, double localized, const std::string& trajectory,
                   const std::string& gt) {
  const ProcessResult eval = Visloc({"eval", "--gt", gt, "--est", trajectory, "--json"});
  ASSERT_EQ(eval.exit_code, 0) << eval.err;
  const double median_m = JsonNumber(eval.out, "translation_m", "median");
  const double median_deg = JsonNumber(eval.out, "rotation_deg", "median");
  std::printf("%s: localized %.3f, median %.2f cm / %.3f deg, max %.2f cm\n", label.c_str(),
              localized, 100 * median_m, median_deg,
              100 * JsonNumber(eval.out, "translation_m", "max"));
  EXPECT_GE(localized, 0.99);
  EXPECT_LE(median_m, 0.02);
  EXPECT_LE(median_deg, 0.3);
}

TEST_P(CameraModelsE2eTest, ChecksMapsAndLocalizesLikeThePinholeRig) {
  const ProcessResult check = Visloc({"dataset", "check", Rig() + "/map_square", "--json"});
  ASSERT_EQ(check.exit_code, 0) << check.out << check.err;
  EXPECT_LT(JsonNumber(check.out, "row_difference_median_px"), 0.3);
  const ProcessResult info = Visloc({"map", "info", Rig() + "/map.db", "--json"});
  ASSERT_EQ(info.exit_code, 0) << info.err;
  EXPECT_THAT(info.out, HasSubstr(GetParam() == "fisheye" ? "\"lens_model\":\"equidistant\""
                                                          : "\"lens_model\":\"radial-tangential\""));
  const std::string trajectory = dir_.File("est.tum");
  const ProcessResult localize =
      Visloc({"localize", "--map", Rig() + "/map.db", "--dataset", Rig() + "/query_square",
              "--trajectory", trajectory, "--json"});
  ASSERT_EQ(localize.exit_code, 0) << localize.err;
  ExpectTargets(GetParam() + " in-process", JsonNumber(localize.out, "localized_fraction"),
                trajectory, Rig() + "/query_square/groundtruth_map.tum");
}

TEST_P(CameraModelsE2eTest, StreamsThroughTheServer) {
  std::filesystem::create_directories(dir_.File("maps"));
  std::filesystem::copy_file(Rig() + "/map.db", dir_.File("maps/rig.db"));
  ServerProcess server(VISLOC_SERVER_PATH, dir_.File("maps"));
  const std::string trajectory = dir_.File("stream.tum");
  const ProcessResult stream =
      Visloc({"stream", "--server", server.address(), "--map", "rig", "--dataset",
              Rig() + "/query_square", "--rate", "0", "--trajectory", trajectory, "--json"});
  ASSERT_EQ(stream.exit_code, 0) << stream.err;
  EXPECT_EQ(JsonNumber(stream.out, "errors"), 0);
  ExpectTargets(GetParam() + " through the server", JsonNumber(stream.out, "localized_fraction"),
                trajectory, Rig() + "/query_square/groundtruth_map.tum");
}

INSTANTIATE_TEST_SUITE_P(Lenses, CameraModelsE2eTest, ::testing::Values("pinhole", "fisheye"),
                         [](const auto& info) { return info.param; });

}  // namespace
}  // namespace visloc
