// Relocalization's two feature passes, in-process on the rendered fixture (the engine the
// Relocalize RPC and the sessions run): the tracking features first, the features at every scale
// only when those verify no candidate, with the same acceptance test for both.

#include <gtest/gtest.h>

#include <memory>

#include "core/localization/localizer.h"
#include "core/localization/query_pipeline.h"
#include "dataset/dataset.h"
#include "dataset/tum.h"
#include "mapstore/map_store.h"

namespace visloc {
namespace {

const std::string kData = VISLOC_LOCALIZATION_DATA;

class RelocalizationPassesTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    map_ = std::make_shared<const LocalizationMap>(mapstore::LoadMap(kData + "/map.db"));
    query_ = std::make_unique<Dataset>(ReadDataset(kData + "/query_square"));
    truth_ = std::make_unique<Trajectory>(ReadTum(kData + "/query_square/groundtruth_map.tum"));
  }
  static void TearDownTestSuite() {
    map_.reset();
    query_.reset();
    truth_.reset();
  }

  static cv::Mat Image(int frame) {
    return LoadGreyImage(query_->frames[frame].left_path, query_->left.camera.width(),
                         query_->left.camera.height());
  }
  static Rigid3d MapFromCam(int frame) {
    return *InterpolateAt(*truth_, query_->frames[frame].timestamp_ns, 1'000'000);
  }
  static double ErrorM(const PoseFix& fix, int frame) {
    return (fix.cam_from_map.Inverse().translation - MapFromCam(frame).translation).norm();
  }
  static QueryPipeline Pipeline(const LocalizerOptions& options) {
    return QueryPipeline(map_, query_->left.camera, options);
  }

  static inline std::shared_ptr<const LocalizationMap> map_;
  static inline std::unique_ptr<Dataset> query_;
  static inline std::unique_ptr<Trajectory> truth_;
};

TEST_F(RelocalizationPassesTest, AViewOfTheMapIsFoundWithTheTrackingFeaturesAlone) {
  const QueryPipeline pipeline = Pipeline(LocalizerOptions{});
  for (int frame : {5, 40, 80}) {
    const RelocalizationResult found = pipeline.RelocalizeImage(Image(frame));
    ASSERT_TRUE(found.success) << frame;
    EXPECT_EQ(found.feature_passes, 1) << frame;
    EXPECT_LT(ErrorM(found.fix, frame), 0.02) << frame;
  }
}

// Tracking features too few to verify anything (25 corners cannot give the 40 verified inliers
// a candidate needs): the second pass finds the view exactly as the full features alone do.
TEST_F(RelocalizationPassesTest, WhatTheTrackingFeaturesMissTheSecondPassFindsAsTheFullOnesAlone) {
  LocalizerOptions few;
  few.max_query_features = 25;
  LocalizerOptions full_only;
  full_only.relocalize_with_tracking_features_first = false;
  const QueryPipeline cascade = Pipeline(few), full = Pipeline(full_only);
  const cv::Mat image = Image(40);
  const RelocalizationResult found = cascade.RelocalizeImage(image);
  const RelocalizationResult alone = full.RelocalizeImage(image);
  ASSERT_TRUE(found.success);
  ASSERT_TRUE(alone.success);
  EXPECT_EQ(found.feature_passes, 2);
  EXPECT_EQ(alone.feature_passes, 1);
  EXPECT_EQ(found.keyframe, alone.keyframe);
  EXPECT_EQ(found.fix.inliers, alone.fix.inliers);
  EXPECT_EQ(found.fix.cam_from_map.translation, alone.fix.cam_from_map.translation);
  EXPECT_LT(ErrorM(found.fix, 40), 0.02);
  // Both passes' time is counted.
  EXPECT_GT(found.times.features_ms, 0.0);
  EXPECT_GE(found.ms, found.times.features_ms + found.times.matching_ms);
}

TEST_F(RelocalizationPassesTest, AnImageOfNothingInTheMapTakesBothPassesAndIsRefused) {
  const QueryPipeline pipeline = Pipeline(LocalizerOptions{});
  const Dataset outside = ReadDataset(kData + "/outofmap");
  const cv::Mat image = LoadGreyImage(outside.frames.back().left_path, outside.left.camera.width(),
                                      outside.left.camera.height());
  const RelocalizationResult found = pipeline.RelocalizeImage(image);
  EXPECT_FALSE(found.success);
  EXPECT_EQ(found.feature_passes, 2);
}

// In a session, a frame whose prior is wrong (the robot was carried off) has its tracking
// features already: relocalization tries them before extracting at every scale. A session's
// first frame is relocalized as the RPC's image is; after a frame that neither found (out of
// the map), the next goes to the full features directly, until the robot is found.
TEST_F(RelocalizationPassesTest, ASessionRelocalizesWithTheFeaturesItTrackedWith) {
  Localizer session(map_, query_->left.camera, LocalizerOptions{});
  FrameInput input;
  input.timestamp_ns = query_->frames[60].timestamp_ns;
  input.image = Image(60);
  // Where the robot was: a metre aside and facing the other way.
  Rigid3d elsewhere = MapFromCam(60);
  elsewhere.translation += Eigen::Vector3d(1.0, 0.0, 0.5);
  elsewhere.rotation =
      elsewhere.rotation * Eigen::Quaterniond(Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitY()));
  input.map_from_cam_hint = elsewhere;
  const LocalizationResult carried = session.Process(input);
  EXPECT_EQ(carried.source, PoseSource::kRelocalization);
  EXPECT_TRUE(carried.relocalization.found);
  EXPECT_EQ(carried.relocalization.feature_passes, 1);
  EXPECT_GT(carried.stats.features, 0);  // The tracking features, extracted for the prior.

  const Dataset outside = ReadDataset(kData + "/outofmap");
  const cv::Mat nowhere = LoadGreyImage(outside.frames.back().left_path,
                                        outside.left.camera.width(), outside.left.camera.height());
  Localizer lost(map_, query_->left.camera, LocalizerOptions{});
  input.map_from_cam_hint.reset();
  std::vector<int> passes;
  for (int i = 0; i < 3; ++i) {
    input.timestamp_ns += 66'000'000;
    input.image = i < 2 ? nowhere : Image(60);
    const LocalizationResult r = lost.Process(input);
    passes.push_back(r.relocalization.feature_passes);
    EXPECT_EQ(r.relocalization.found, i == 2) << i;
  }
  EXPECT_EQ(passes, (std::vector<int>{2, 1, 1}));
}

}  // namespace
}  // namespace visloc
