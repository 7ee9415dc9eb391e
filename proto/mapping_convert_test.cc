// Mapping over the link on the wire: a rig round-trips to the right camera's pose from the left,
// rigs without a baseline or a right camera are refused by name, and job options keep `visloc
// map build`'s defaults where the client sends zeros.

#include "proto/mapping_convert.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "core/util/check.h"

namespace visloc {
namespace {

using ::testing::HasSubstr;

const Camera kLeft(752, 480, 458.6, 457.3, 367.2, 248.4, Lens(-0.28, 0.07, 1e-4, 2e-5));
const Camera kRight(752, 480, 457.6, 456.1, 379.9, 255.2, Lens(-0.28, 0.07, -1e-4, -5e-5));

std::string RefusalOf(const v1::StereoRig& rig) {
  try {
    proto::FromProto(rig, proto::WireLimits{});
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

std::string RefusalOf(const v1::MappingOptions& options) {
  try {
    proto::FromProto(options);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(MappingConvertTest, TheRigRoundTripsToTheRightCameraFromTheLeft) {
  const Rigid3d body_from_left(Eigen::Quaterniond(0.7, 0.1, -0.1, 0.7).normalized(),
                               Eigen::Vector3d(-0.02, -0.06, 0.01));
  const Rigid3d body_from_right(Eigen::Quaterniond(0.7, 0.11, -0.1, 0.7).normalized(),
                                Eigen::Vector3d(-0.02, 0.05, 0.01));
  v1::StereoRig wire;
  proto::ToProto(kLeft, kRight, body_from_left, body_from_right, &wire);
  const proto::StereoRigInput rig = proto::FromProto(wire, proto::WireLimits{});
  EXPECT_EQ(rig.left.Params(), kLeft.Params());
  EXPECT_EQ(rig.right.Params(), kRight.Params());
  const Rigid3d expected = body_from_right.Inverse() * body_from_left;
  EXPECT_LT((rig.right_from_left.translation - expected.translation).norm(), 1e-12);
  EXPECT_LT(rig.right_from_left.rotation.angularDistance(expected.rotation), 1e-12);
}

TEST(MappingConvertTest, RigsThatCannotMapAreRefusedByName) {
  v1::StereoRig wire;
  proto::ToProto(kLeft, kRight, Rigid3d::Identity(), Rigid3d::Identity(), &wire);
  EXPECT_THAT(RefusalOf(wire), HasSubstr("needs a baseline"));
  wire.clear_body_from_right();
  EXPECT_THAT(RefusalOf(wire), HasSubstr("rig.body_from_right"));
  wire.clear_right();
  EXPECT_THAT(RefusalOf(wire), HasSubstr("both cameras"));
}

TEST(MappingConvertTest, ZeroOptionsAreMapBuildsDefaultsAndBadOnesAreNamed) {
  const proto::MappingJobOptions defaults = proto::FromProto(v1::MappingOptions{});
  const mapping::MapBuilderOptions builder;
  EXPECT_EQ(defaults.builder.features.kind, "harris_surf16");
  EXPECT_EQ(defaults.builder.keyframes.translation_m, builder.keyframes.translation_m);
  EXPECT_TRUE(defaults.builder.loop_closure.enabled);
  EXPECT_TRUE(defaults.builder.disparity_calibration.enabled);
  EXPECT_EQ(defaults.min_points, 100);
  EXPECT_FALSE(defaults.replace);

  v1::MappingOptions wire;
  wire.set_features("orb");
  wire.set_loop_closure(false);
  wire.set_keyframe_translation_m(0.3);
  wire.set_replace(true);
  const proto::MappingJobOptions set = proto::FromProto(wire);
  EXPECT_EQ(set.builder.features.kind, "orb");
  EXPECT_FALSE(set.builder.loop_closure.enabled);
  EXPECT_TRUE(set.builder.disparity_calibration.enabled);
  EXPECT_EQ(set.builder.keyframes.translation_m, 0.3);
  EXPECT_TRUE(set.replace);

  wire.set_keyframe_translation_m(-1);
  EXPECT_THROW(proto::FromProto(wire), InputError);
  wire.set_keyframe_translation_m(0);
  wire.set_features("sift");
  EXPECT_THROW(proto::FromProto(wire), InputError);
}

TEST(MappingConvertTest, AKnownDisparityCorrectionIsTakenAndNotEstimatedAgain) {
  v1::MappingOptions wire;
  wire.mutable_disparity_correction()->set_offset_px(-0.12);
  wire.mutable_disparity_correction()->set_right_camera_yaw_deg(-0.075);
  const proto::MappingJobOptions job = proto::FromProto(wire);
  ASSERT_TRUE(job.builder.disparity_calibration.known.has_value());
  EXPECT_EQ(job.builder.disparity_calibration.known->offset_px, -0.12);
  EXPECT_NEAR(job.builder.disparity_calibration.known->yaw_rad, -0.075 * M_PI / 180.0, 1e-15);
  EXPECT_FALSE(job.builder.disparity_calibration.enabled);
  EXPECT_NO_THROW(job.builder.Check());
  wire.set_disparity_calibration(false);
  EXPECT_NO_THROW(proto::FromProto(wire));
  wire.set_disparity_calibration(true);
  EXPECT_THAT(RefusalOf(wire), HasSubstr("not estimated again"));
  wire.clear_disparity_calibration();
  wire.mutable_disparity_correction()->set_right_camera_yaw_deg(8.0);
  EXPECT_THAT(RefusalOf(wire), HasSubstr("options.disparity_correction.right_camera_yaw_deg"));
}

TEST(MappingConvertTest, ALostFrameSaysWhatTheMapperSaw) {
  mapping::MapBuilderProgress progress;
  progress.frames = 7;
  progress.keyframes = 3;
  progress.last_tracked = false;
  progress.tracked = 4;
  progress.features = 900;
  progress.stereo_matches = 12;
  v1::MappingProgress wire;
  proto::ToProto(progress, &wire);
  EXPECT_EQ(wire.state(), v1::MAPPING_LOST);
  EXPECT_EQ(wire.frame_index(), 6u);
  EXPECT_FALSE(wire.has_pose());
  EXPECT_THAT(wire.error(), HasSubstr("12 of them matched in the right image"));
  EXPECT_THAT(wire.error(), HasSubstr("too few stereo matches"));
}

TEST(MappingConvertTest, StatesAreNamedWithoutTheirPrefix) {
  EXPECT_EQ(proto::MappingStateText(v1::MAPPING_FRAME_ERROR), "frame_error");
  EXPECT_EQ(proto::MappingStateText(v1::MAPPING_PUBLISHED), "published");
}

}  // namespace
}  // namespace visloc
