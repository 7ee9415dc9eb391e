#include "mapping/session_merge.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "core/util/check.h"
#include "core/util/temp_dir.h"
#include "dataset/dataset.h"
#include "mapping/dataset_mapping.h"
#include "sim/generate.h"

namespace visloc::mapping {
namespace {

using ::testing::HasSubstr;

// Frames held in memory, as a server holding a robot's stream would: no dataset, no files.
class MemorySource final : public StereoSource {
 public:
  MemorySource(std::string name, Camera left, Camera right, Rigid3d right_from_left,
               std::vector<StereoImages> frames)
      : name_(std::move(name)),
        left_(std::move(left)),
        right_(std::move(right)),
        right_from_left_(right_from_left),
        frames_(std::move(frames)) {}

  std::string name() const override { return name_; }
  const Camera& left_camera() const override { return left_; }
  const Camera& right_camera() const override { return right_; }
  Rigid3d right_from_left() const override { return right_from_left_; }
  int size() const override { return static_cast<int>(frames_.size()); }
  int64_t TimestampNs(int index) const override { return frames_[index].timestamp_ns; }
  StereoImages Read(int index) const override { return frames_[index]; }

 private:
  std::string name_;
  Camera left_, right_;
  Rigid3d right_from_left_;
  std::vector<StereoImages> frames_;
};

// The rendered square walk: a map of its first frames, and a later stretch that overlaps it.
class SessionMergeTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    sim::GenerateOptions options;
    options.max_frames = 90;
    options.contact_sheet = false;
    const TempDir dir("visloc_session_merge_test");
    dataset_ = new Dataset(
        ReadDataset(sim::SequenceGenerator(options).Generate("map_square", dir.path()).dir));
    const DatasetSource source(*dataset_);
    for (int i = 0; i < source.size(); ++i) frames_->push_back(source.Read(i));
  }
  static void TearDownTestSuite() {
    delete dataset_;
    dataset_ = nullptr;
  }

  static MemorySource Frames(const std::string& name, int begin, int end,
                             const Camera* left = nullptr) {
    return MemorySource(
        name, left ? *left : dataset_->left.camera, dataset_->right->camera,
        dataset_->right_from_left(),
        std::vector<StereoImages>(frames_->begin() + begin, frames_->begin() + end));
  }

  static Dataset* dataset_;
  static inline std::vector<StereoImages>* frames_ = new std::vector<StereoImages>();
};

Dataset* SessionMergeTest::dataset_ = nullptr;

TEST_F(SessionMergeTest, ASessionOfFramesInMemoryExtendsTheMapWhereGroundTruthPlacesIt) {
  Map map = MapStereoFrames(Frames("first", 0, 50), MapBuilderOptions{},
                            MapMetadata{"square", 0, "memory", "test", ""});
  // The rig's disparity correction as an earlier build recorded it (a small one: this rig has
  // none): the session, of the same rig, is mapped with it rather than estimating its own.
  map.metadata.disparity_correction = DisparityCorrection{0.05, 1e-5};
  SessionMergeStats stats;
  std::vector<SessionMergeProgress::Stage> stages;
  const Map extended =
      MergeSession(map, Frames("later", 30, 90), SessionMergeKind::kExtend, SessionMergeOptions{},
                   &stats, [&](const SessionMergeProgress& p) {
                     if (stages.empty() || stages.back() != p.stage) stages.push_back(p.stage);
                   });

  EXPECT_GT(extended.keyframes.size(), map.keyframes.size());
  EXPECT_EQ(stats.map_points, static_cast<int>(map.points.size()));
  EXPECT_EQ(stats.registration.frames, 60);
  EXPECT_GE(stats.registration.agreeing_frames, 3);
  EXPECT_THAT(extended.metadata.lineage, HasSubstr("extend("));
  EXPECT_THAT(extended.metadata.lineage, HasSubstr("later"));
  EXPECT_EQ(stats.session_build.disparity_correction, *map.metadata.disparity_correction);
  EXPECT_EQ(stats.session_build.calibration_passes, 0);
  EXPECT_EQ(extended.metadata.disparity_correction, map.metadata.disparity_correction);
  EXPECT_EQ(stages,
            (std::vector<SessionMergeProgress::Stage>{SessionMergeProgress::Stage::kLocalizing,
                                                      SessionMergeProgress::Stage::kMapping}));
  // The session's frame is its first image's camera: in the map, where ground truth has it.
  const Trajectory truth = dataset_->GroundTruthLeftCam();
  const Rigid3d map_from_truth = map.keyframes.front().map_from_cam * truth.front().pose.Inverse();
  const Rigid3d expected = map_from_truth * truth[30].pose;
  EXPECT_LT((stats.map_from_session.translation - expected.translation).norm(), 0.03);
}

TEST_F(SessionMergeTest, ASessionOfAnotherCameraIsRefusedByName) {
  const Map map = MapStereoFrames(Frames("first", 0, 20), MapBuilderOptions{},
                                  MapMetadata{"square", 0, "memory", "test", ""});
  const Camera& left = dataset_->left.camera;
  const Camera other(left.width(), left.height(), left.fx() * 1.1, left.fy() * 1.1, left.cx(),
                     left.cy());
  SessionMergeStats stats;
  try {
    MergeSession(map, Frames("the-other-robot", 20, 40, &other), SessionMergeKind::kUpdate,
                 SessionMergeOptions{}, &stats);
    FAIL() << "a session of another camera was merged";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("the session the-other-robot's left camera"));
  }
}

TEST_F(SessionMergeTest, BadOptionsAreRefusedBeforeAnyWork) {
  SessionMergeOptions options;
  options.update.merge.min_inliers = 2;
  EXPECT_THROW(options.Check(), CheckError);
  options = SessionMergeOptions{};
  options.registration.min_agreeing_frames = 0;
  EXPECT_THROW(options.Check(), CheckError);
}

}  // namespace
}  // namespace visloc::mapping
