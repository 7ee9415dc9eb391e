#include <gtest/gtest.h>

#include "core/geometry/trajectory.h"
#include "core/map/synthetic_map.h"
#include "core/map/visibility_kernel.h"
#include "core/util/check.h"
#include "core/util/random.h"
#include "core/util/temp_dir.h"
#include "dataset/tum.h"
#include "mapping/dataset_mapping.h"
#include "mapping/reprojection_cost.h"
#include "mapping/stereo_frame.h"
#include "mapping/visibility_learning.h"
#include "sim/generate.h"
#include "sim/renderer.h"
#include "sim/sequences.h"

namespace visloc::mapping {
namespace {

const RectifiedIntrinsics kIntrinsics{160.0, 159.5, 119.5, 0.144};

// Compares a cost function's Jacobians with central numeric differences of the same functor.
template <typename Functor, int kResiduals>
void ExpectJacobiansMatchNumeric(ceres::CostFunction* analytic, Functor* functor) {
  std::unique_ptr<ceres::CostFunction> autodiff(analytic);
  ceres::NumericDiffCostFunction<Functor, ceres::CENTRAL, kResiduals, 4, 3, 3> numeric(functor);
  const Eigen::Quaterniond q = RotationFromRollPitchYaw(0.1, -0.2, 0.3);
  double rotation[4] = {q.x(), q.y(), q.z(), q.w()};
  double translation[3] = {0.1, -0.05, 0.2};
  double point[3] = {0.4, -0.3, 3.0};
  const double* parameters[3] = {rotation, translation, point};
  double residual_a[3], residual_n[3];
  double ja[3][kResiduals * 4], jn[3][kResiduals * 4];
  double* jacobians_a[3] = {ja[0], ja[1], ja[2]};
  double* jacobians_n[3] = {jn[0], jn[1], jn[2]};
  ASSERT_TRUE(autodiff->Evaluate(parameters, residual_a, jacobians_a));
  ASSERT_TRUE(numeric.Evaluate(parameters, residual_n, jacobians_n));
  const int sizes[3] = {4, 3, 3};
  for (int block = 0; block < 3; ++block) {
    for (int i = 0; i < kResiduals * sizes[block]; ++i) {
      EXPECT_NEAR(ja[block][i], jn[block][i], 1e-5 * (1 + std::abs(jn[block][i])))
          << "block " << block << " entry " << i;
    }
  }
  for (int r = 0; r < kResiduals; ++r) EXPECT_DOUBLE_EQ(residual_a[r], residual_n[r]);
}

TEST(ReprojectionCostTest, StereoJacobiansMatchNumericDerivatives) {
  const Eigen::Vector2d left(170.0, 100.0);
  ExpectJacobiansMatchNumeric<StereoReprojectionCost, 3>(
      StereoReprojectionCost::Create(left, 160.0, kIntrinsics, 8.0),
      new StereoReprojectionCost(left, 160.0, kIntrinsics, 8.0));
}

TEST(ReprojectionCostTest, MonoJacobiansMatchNumericDerivatives) {
  const Eigen::Vector2d left(170.0, 100.0);
  ExpectJacobiansMatchNumeric<MonoReprojectionCost, 2>(
      MonoReprojectionCost::Create(left, kIntrinsics), new MonoReprojectionCost(left, kIntrinsics));
}

TEST(ReprojectionCostTest, ZeroAtTheTruePose) {
  const Eigen::Vector3d point(0.3, -0.2, 2.5);
  const Eigen::Vector2d left(kIntrinsics.f * 0.3 / 2.5 + kIntrinsics.cx,
                             kIntrinsics.f * -0.2 / 2.5 + kIntrinsics.cy);
  const double right_x = kIntrinsics.f * (0.3 - 0.144) / 2.5 + kIntrinsics.cx;
  StereoReprojectionCost cost(left, right_x, kIntrinsics, 8.0);
  const double rotation[4] = {0, 0, 0, 1}, translation[3] = {0, 0, 0};
  double residuals[3];
  cost(rotation, translation, point.data(), residuals);
  for (double r : residuals) EXPECT_NEAR(r, 0.0, 1e-12);
}

// Stereo matches' disparity errors (px) against the rendered depth, with the patch refinement
// of `refine_radius_px` (0: the correlation peak alone).
std::vector<double> DisparityErrorsPx(int refine_radius_px, int* matches, size_t* features) {
  const sim::StereoRig rig = sim::MakeRig(sim::RigOptions{});
  sim::RoomOptions room;
  room.texel_m = 0.006;
  const sim::World world = sim::MakeRoom(room);
  const Rigid3d body(RotationFromRollPitchYaw(0, 0.02, 0.4), Eigen::Vector3d(-0.5, -0.6, 1.45));
  const sim::Renderer left_renderer(rig.left.camera, 2), right_renderer(rig.right.camera, 2);
  cv::Mat depth;
  sim::SensorModel sensor;
  Rng noise(1);
  const cv::Mat left = sensor.Capture(
      left_renderer.RenderRadiance(world, body * rig.left.body_from_cam, 0, &depth), &noise);
  const cv::Mat right = sensor.Capture(
      right_renderer.RenderRadiance(world, body * rig.right.body_from_cam, 0), &noise);
  const StereoRectifier rectifier(rig.left.camera, rig.right.camera,
                                  rig.right.body_from_cam.Inverse() * rig.left.body_from_cam);
  const auto extractor = CreateFeatureExtractor(DefaultFeatureSettings("harris_surf16"));
  StereoMatchOptions options;
  options.refine_patch_radius_px = refine_radius_px;
  const StereoFrame frame = BuildStereoFrame(left, right, *extractor, rectifier, options);
  // A corner on a depth edge belongs to either surface, so the truth is the closest of the 3x3
  // neighbourhood's disparities.
  const double fb = rectifier.rectified_camera().fx() * rectifier.baseline_m();
  std::vector<double> errors_px;
  for (size_t i = 0; i < frame.left.size(); ++i) {
    if (!frame.HasDepth(i)) continue;
    const Eigen::Vector2f& px = frame.left.keypoints[i].pixel;
    const int x = static_cast<int>(std::lround(px.x())), y = static_cast<int>(std::lround(px.y()));
    const double estimated = fb / frame.point_in_rect[i].z();
    double best = 1e9;
    for (int dy = -1; dy <= 1; ++dy) {
      for (int dx = -1; dx <= 1; ++dx) {
        const float z = depth.at<float>(y + dy, x + dx);
        if (z > 0) best = std::min(best, std::abs(estimated - fb / z));
      }
    }
    if (best < 1e9) errors_px.push_back(best);
  }
  std::sort(errors_px.begin(), errors_px.end());
  *matches = frame.stereo_matches();
  *features = frame.left.size();
  return errors_px;
}

TEST(StereoFrameTest, TriangulatedDepthMatchesTheRenderedDepth) {
  int matches = 0;
  size_t features = 0;
  const std::vector<double> errors_px = DisparityErrorsPx(7, &matches, &features);
  const size_t wrong =
      std::count_if(errors_px.begin(), errors_px.end(), [](double e) { return e > 1.0; });
  std::printf(
      "%d stereo matches of %zu features; median disparity error %.3f px, %zu beyond 1 px\n",
      matches, features, errors_px[errors_px.size() / 2], wrong);
  EXPECT_GT(matches, 500);
  EXPECT_LT(errors_px[errors_px.size() / 2], 0.15);
  EXPECT_LT(static_cast<double>(wrong) / errors_px.size(), 0.03);
}

TEST(StereoFrameTest, TheCorrelationPeakAloneIsGoodToAFewTenthsOfAPixel) {
  // The row search correlates at the keypoint's nearest whole pixel; the keypoint shares that
  // disparity (it once got the fraction of a pixel between them added, half a pixel off at worst).
  int matches = 0;
  size_t features = 0;
  const std::vector<double> errors_px = DisparityErrorsPx(0, &matches, &features);
  const double median = errors_px[errors_px.size() / 2];
  const double p90 = errors_px[errors_px.size() * 9 / 10];
  std::printf("correlation peak alone: median disparity error %.3f px, 90%% within %.3f px\n",
              median, p90);
  EXPECT_LT(median, 0.15);
  EXPECT_LT(p90, 0.3);
}

class MapBuilderTest : public ::testing::TestWithParam<bool> {};

// With and without lens distortion: rectification and raw-pixel observations must agree.
TEST_P(MapBuilderTest, VisualOdometryFollowsAShortSequence) {
  TempDir dir;
  sim::GenerateOptions options;
  options.rig.distortion = GetParam();
  options.max_frames = 45;  // 3 s of walking, ~0.6 m
  options.contact_sheet = false;
  const sim::GenerateStats generated =
      sim::SequenceGenerator(options).Generate("map_square", dir.path());
  const Dataset dataset = ReadDataset(generated.dir);
  DatasetMappingOptions builder_options;
  builder_options.builder.loop_closure.enabled = false;
  MapBuildStats stats;
  Trajectory estimate;
  const Map map = BuildMap(dataset, builder_options, {"vo", 0, "test", "test", ""}, &stats, &estimate);
  const Trajectory truth = ReadTum(generated.dir + "/groundtruth_map.tum");
  ASSERT_EQ(estimate.size(), truth.size());
  double worst_m = 0;
  for (size_t i = 0; i < truth.size(); ++i) {
    worst_m = std::max(worst_m, (estimate[i].pose.translation - truth[i].pose.translation).norm());
  }
  std::printf("VO over %zu frames: worst position error %.2f cm, %d keyframes, %d points\n",
              truth.size(), 100 * worst_m, stats.keyframes, stats.points);
  EXPECT_LT(worst_m, 0.02);
  EXPECT_EQ(stats.tracking_failures, 0);
  EXPECT_GE(stats.keyframes, 3);  // ~0.6 m at one keyframe per 0.15 m
  EXPECT_LT(stats.reprojection_rmse_px, 0.6);
  EXPECT_TRUE(FindMapProblems(map).empty());
}

INSTANTIATE_TEST_SUITE_P(PinholeAndDistorted, MapBuilderTest, ::testing::Bool());

// The first `frames` frames of a catalogue sequence, rendered into `dir`.
Dataset RenderShort(const std::string& sequence, int frames, const TempDir& dir) {
  sim::GenerateOptions options;
  options.max_frames = frames;
  options.contact_sheet = false;
  return ReadDataset(sim::SequenceGenerator(options).Generate(sequence, dir.path()).dir);
}

TEST(MapBuilderInputTest, MonocularDatasetsAreRefused) {
  TempDir dir;
  Dataset dataset = RenderShort("straight", 2, dir);
  dataset.right.reset();
  EXPECT_THROW(BuildMap(dataset, DatasetMappingOptions{}, {"m", 0, "", "", ""}, nullptr), InputError);
}

TEST(MapBuilderInputTest, ASingleStereoPairIsAMapOfItsStereoPoints) {
  // A robot that stands still maps from one keyframe: its stereo points have measured depth.
  TempDir dir;
  const Dataset dataset = RenderShort("map_square", 1, dir);
  MapBuildStats stats;
  const Map map = BuildMap(dataset, DatasetMappingOptions{}, {"one", 0, "test", "test", ""}, &stats);
  EXPECT_EQ(stats.keyframes, 1);
  EXPECT_GT(stats.points, 400);
  EXPECT_EQ(stats.observations, stats.points);
  EXPECT_TRUE(FindMapProblems(map).empty());
}

// A hand-made state of two keyframes for the assembly's point rules.
SlamState TwoKeyframes() {
  SlamState state;
  for (int k = 0; k < 2; ++k) {
    SlamKeyframe keyframe;
    keyframe.cam_from_world = Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(-0.1 * k, 0, 0));
    keyframe.features.descriptors = cv::Mat(4, 16, CV_32F, cv::Scalar(0.25f));
    keyframe.features.keypoints.resize(4);
    for (int i = 0; i < 4; ++i) {
      const Eigen::Vector3d point(0.2 * i - 0.3, 0.1, 2.0);
      const Eigen::Vector3d in_cam = keyframe.cam_from_world * point;
      keyframe.left_rect.emplace_back(kIntrinsics.f * in_cam.x() / in_cam.z() + kIntrinsics.cx,
                                      kIntrinsics.f * in_cam.y() / in_cam.z() + kIntrinsics.cy);
      keyframe.right_x_rect.push_back(keyframe.left_rect.back().x() -
                                      kIntrinsics.f * kIntrinsics.baseline_m / in_cam.z());
      keyframe.features.keypoints[i].pixel = keyframe.left_rect.back().cast<float>();
    }
    keyframe.landmark.assign(4, -1);
    state.keyframes.push_back(std::move(keyframe));
  }
  for (int i = 0; i < 4; ++i) {
    Landmark landmark;
    landmark.position_in_world = Eigen::Vector3d(0.2 * i - 0.3, 0.1, 2.0);
    state.landmarks.push_back(landmark);
  }
  return state;
}

TEST(MapAssemblyTest, StereoViewsCountTwiceAndUnconfirmedLandmarksAreLeftOut) {
  SlamState state = TwoKeyframes();
  state.Observe(0, 0, 0);  // stereo, one keyframe: two views, kept
  state.Observe(1, 0, 1);  // mono, one keyframe: one view, left out
  state.keyframes[0].right_x_rect[1] = std::numeric_limits<double>::quiet_NaN();
  state.Observe(2, 0, 2);  // stereo, one keyframe, expected in 10 frames, found in 1: left out
  state.landmarks[2].frames_in_view = 10;
  state.landmarks[2].frames_found = 1;
  state.Observe(3, 0, 3);  // two keyframes: kept however rarely found in frames
  state.Observe(3, 1, 3);
  state.landmarks[3].frames_in_view = 10;
  AssemblyStats stats;
  const Map map = AssembleMap(state, Camera(320, 240, 160, 160, 159.5, 119.5),
                              DefaultFeatureSettings("harris_surf16"), {"m", 0, "", "", ""},
                              Rigid3d::Identity(), Rigid3d::Identity(), kIntrinsics,
                              AssemblyOptions{}, &stats);
  ASSERT_EQ(map.points.size(), 2u);
  EXPECT_TRUE(map.points[0].position_in_map.isApprox(state.landmarks[0].position_in_world));
  EXPECT_TRUE(map.points[1].position_in_map.isApprox(state.landmarks[3].position_in_world));
  EXPECT_EQ(map.points[1].observation_count, 2u);
  EXPECT_EQ(stats.culled_unconfirmed, 1);
  EXPECT_EQ(stats.observations, 3);
  EXPECT_LT(stats.reprojection_rmse_px, 1e-9);
}

TEST(VisibilityLearningTest, KernelRanksKeyframePairsByOverlap) {
  SyntheticMapOptions options;
  options.keyframes = 60;
  options.points = 6000;
  options.observations_per_point = 6;  // Neighbouring keyframes share points; far ones none.
  const Map map = MakeSyntheticMap(options);
  VisibilityLearningStats stats;
  const VisibilityKernel kernel = LearnVisibilityKernel(map, VisibilityLearningOptions{}, &stats);
  EXPECT_LT(stats.final_rmse, stats.initial_rmse);
  const Eigen::MatrixXd overlap = VisibilityOverlap(map);
  // For every keyframe, the kernel's nearest neighbours are the ones with the most overlap.
  int agree = 0, total = 0;
  for (int i = 0; i < options.keyframes; ++i) {
    const Keyframe& a = map.keyframes[i];
    std::vector<std::pair<double, int>> by_kernel;
    for (int j = 0; j < options.keyframes; ++j) {
      if (j == i) continue;
      const Keyframe& b = map.keyframes[j];
      by_kernel.emplace_back(
          -EvaluateKernel(kernel.metric,
                          KernelCues(a.map_from_cam.translation,
                                     a.map_from_cam.rotation * Eigen::Vector3d::UnitZ(),
                                     b.map_from_cam.translation,
                                     b.map_from_cam.rotation * Eigen::Vector3d::UnitZ())),
          j);
    }
    std::sort(by_kernel.begin(), by_kernel.end());
    for (int rank = 0; rank < 4; ++rank) {  // the 4 best by kernel all overlap
      agree += overlap(i, by_kernel[rank].second) > 0.2;
      ++total;
    }
  }
  EXPECT_EQ(agree, total);
}

}  // namespace
}  // namespace visloc::mapping
