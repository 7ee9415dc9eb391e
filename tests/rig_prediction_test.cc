// A rig's prediction made beside its cameras' feature extraction (Localizer::ExtractRig), in
// process on the rendered fixture's front-back rig: tracking with it gives the fix tracking
// without it gives, and a prediction made from another prior is not used.

#include <gtest/gtest.h>

#include <memory>

#include "core/localization/rig_pipeline.h"
#include "dataset/dataset.h"
#include "dataset/tum.h"
#include "mapstore/map_store.h"

namespace visloc {
namespace {

const std::string kData = VISLOC_LOCALIZATION_DATA;
constexpr int kFrame = 10;  // Walking, before the front pair is covered.

class RigPredictionTest : public ::testing::Test {
 protected:
  void SetUp() override {
    map_ = std::make_shared<const LocalizationMap>(mapstore::LoadMap(kData + "/map.db"));
    const Dataset walk = ReadDataset(kData + "/front-back/kidnap");
    ASSERT_EQ(walk.other_cameras.size(), 1u);
    const CameraStream& rear = walk.other_cameras[0];
    rig_.cameras = {walk.left.camera, rear.info.camera};
    rig_.body_from_cam = {walk.left.body_from_cam, rear.info.body_from_cam};
    const FrameRecord& record = walk.frames[kFrame];
    const auto* rear_image = rear.Nearest(record.timestamp_ns, 1'000'000);
    ASSERT_NE(rear_image, nullptr);
    pipeline_ = std::make_unique<RigPipeline>(map_, rig_, LocalizerOptions{});
    const std::string paths[] = {record.left_path, rear_image->second};
    for (size_t c = 0; c < 2; ++c) {
      const Camera& camera = rig_.cameras[c];
      frames_.push_back(
          pipeline_->camera(c).Extract(LoadGreyImage(paths[c], camera.width(), camera.height())));
    }
    const Trajectory truth = ReadTum(kData + "/front-back/kidnap/groundtruth_map.tum");
    map_from_cam_ = *InterpolateAt(truth, record.timestamp_ns, 1'000'000);
  }

  std::vector<const QueryFrame*> Frames() const { return {&frames_[0], &frames_[1]}; }
  RigTracker::Prediction PredictionFrom(const Rigid3d& prior_ref_from_map) const {
    RigTracker::Prediction prediction;
    prediction.prior_ref_from_map = prior_ref_from_map;
    for (size_t c = 0; c < 2; ++c) {
      prediction.cameras.push_back(pipeline_->tracker()->PredictCamera(c, prior_ref_from_map));
    }
    return prediction;
  }

  std::shared_ptr<const LocalizationMap> map_;
  CameraRig rig_;
  std::unique_ptr<RigPipeline> pipeline_;
  std::vector<QueryFrame> frames_;
  Rigid3d map_from_cam_;
};

void ExpectSameFix(const PoseFix& a, const PoseFix& b) {
  EXPECT_EQ(a.success, b.success);
  EXPECT_EQ(a.cam_from_map.rotation.coeffs(), b.cam_from_map.rotation.coeffs());
  EXPECT_EQ(a.cam_from_map.translation, b.cam_from_map.translation);
  EXPECT_EQ(a.predicted, b.predicted);
  EXPECT_EQ(a.putatives, b.putatives);
  EXPECT_EQ(a.inliers, b.inliers);
}

TEST_F(RigPredictionTest, TrackingWithThePriorsPredictionGivesTheFixTrackingWithoutItGives) {
  // A prior 3 cm off, as a filter's prediction is.
  const Rigid3d prior_ref_from_map =
      Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.03, 0.0, 0.0)) *
      map_from_cam_.Inverse();
  const RigTracker& tracker = *pipeline_->tracker();
  const PoseFix without = tracker.Track(Frames(), prior_ref_from_map);
  ASSERT_TRUE(without.success);
  EXPECT_LT((without.cam_from_map.Inverse().translation - map_from_cam_.translation).norm(), 0.02);
  ExpectSameFix(tracker.Track(Frames(), prior_ref_from_map, PredictionFrom(prior_ref_from_map)),
                without);
}

TEST_F(RigPredictionTest, APredictionMadeFromAnotherPriorIsNotUsed) {
  const Rigid3d prior_ref_from_map = map_from_cam_.Inverse();
  // Made from a pose 30 cm and 10 degrees away (a held fix's prior differs so from the filter's).
  const Rigid3d elsewhere =
      Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(10.0 * M_PI / 180.0, Eigen::Vector3d::UnitY())),
              Eigen::Vector3d(0.3, 0.0, 0.0)) *
      prior_ref_from_map;
  const RigTracker& tracker = *pipeline_->tracker();
  const PoseFix without = tracker.Track(Frames(), prior_ref_from_map);
  ASSERT_TRUE(without.success);
  ExpectSameFix(tracker.Track(Frames(), prior_ref_from_map, PredictionFrom(elsewhere)), without);
}

}  // namespace
}  // namespace visloc
