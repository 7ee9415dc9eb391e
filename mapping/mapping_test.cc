#include <gtest/gtest.h>

#include "core/geometry/trajectory.h"
#include "core/map/synthetic_map.h"
#include "core/map/visibility_kernel.h"
#include "core/util/check.h"
#include "core/util/random.h"
#include "core/util/temp_dir.h"
#include "dataset/tum.h"
#include "mapping/dataset_mapping.h"
#include "mapping/frame_tracker.h"
#include "mapping/keyframes.h"
#include "mapping/reprojection_cost.h"
#include "mapping/stereo_frame.h"
#include "mapping/visibility_learning.h"
#include "sim/generate.h"
#include "sim/renderer.h"
#include "sim/sequences.h"

namespace visloc::mapping {
namespace {

const RectifiedIntrinsics kIntrinsics{160.0, 159.5, 119.5, 0.144};

// Compares a cost function's Jacobians with central numeric differences of the same functor, at
// `parameters` (one vector per block, of the sizes kBlocks).
template <typename Functor, int kResiduals, int... kBlocks>
void ExpectJacobiansMatchNumeric(ceres::CostFunction* analytic, Functor* functor,
                                 std::vector<std::vector<double>> parameters) {
  std::unique_ptr<ceres::CostFunction> cost(analytic);
  ceres::NumericDiffCostFunction<Functor, ceres::CENTRAL, kResiduals, kBlocks...> numeric(functor);
  const std::vector<int> sizes = {kBlocks...};
  std::vector<const double*> blocks;
  std::vector<std::vector<double>> ja, jn;
  std::vector<double*> jacobians_a, jacobians_n;
  for (size_t b = 0; b < sizes.size(); ++b) {
    blocks.push_back(parameters[b].data());
    ja.emplace_back(kResiduals * sizes[b]);
    jn.emplace_back(kResiduals * sizes[b]);
  }
  for (size_t b = 0; b < sizes.size(); ++b) {
    jacobians_a.push_back(ja[b].data());
    jacobians_n.push_back(jn[b].data());
  }
  double residual_a[kResiduals], residual_n[kResiduals];
  ASSERT_TRUE(cost->Evaluate(blocks.data(), residual_a, jacobians_a.data()));
  ASSERT_TRUE(numeric.Evaluate(blocks.data(), residual_n, jacobians_n.data()));
  for (size_t block = 0; block < sizes.size(); ++block) {
    for (int i = 0; i < kResiduals * sizes[block]; ++i) {
      EXPECT_NEAR(ja[block][i], jn[block][i], 1e-5 * (1 + std::abs(jn[block][i])))
          << "block " << block << " entry " << i;
    }
  }
  for (int r = 0; r < kResiduals; ++r) EXPECT_DOUBLE_EQ(residual_a[r], residual_n[r]);
}

// A pose and a point in front of it, as parameter blocks.
std::vector<std::vector<double>> PoseAndPoint() {
  const Eigen::Quaterniond q = RotationFromRollPitchYaw(0.1, -0.2, 0.3);
  return {{q.x(), q.y(), q.z(), q.w()}, {0.1, -0.05, 0.2}, {0.4, -0.3, 3.0}};
}

TEST(ReprojectionCostTest, StereoJacobiansMatchNumericDerivatives) {
  const Eigen::Vector2d left(170.0, 100.0);
  std::vector<std::vector<double>> parameters = PoseAndPoint();
  parameters.push_back({0.4, 0.002, 0.0});  // A disparity correction change: 0.4 px, 0.11 deg.
  ExpectJacobiansMatchNumeric<StereoReprojectionCost, 3, 4, 3, 3, kCorrectionBlockSize>(
      StereoReprojectionCost::Create(left, 160.0, kIntrinsics, 8.0),
      new StereoReprojectionCost(left, 160.0, kIntrinsics, 8.0), parameters);
}

// A left-only observation in the stereo layout: the left residual as MonoReprojectionCost has
// it, and a disparity row that is zero with zero derivatives whatever the parameters.
TEST(ReprojectionCostTest, LeftOnlyHasTheMonoResidualAndNoDisparityRow) {
  const Eigen::Vector2d left(170.0, 100.0);
  std::vector<std::vector<double>> parameters = PoseAndPoint();
  parameters.push_back({0.4, 0.002, 0.0});
  std::unique_ptr<StereoReprojectionCost> left_only(
      StereoReprojectionCost::LeftOnly(left, kIntrinsics));
  ExpectJacobiansMatchNumeric<StereoReprojectionCost, 3, 4, 3, 3, kCorrectionBlockSize>(
      StereoReprojectionCost::LeftOnly(left, kIntrinsics),
      StereoReprojectionCost::LeftOnly(left, kIntrinsics), parameters);
  double stereo_layout[3], mono[2];
  (*left_only)(parameters[0].data(), parameters[1].data(), parameters[2].data(),
               parameters[3].data(), stereo_layout);
  MonoReprojectionCost(left, kIntrinsics)(parameters[0].data(), parameters[1].data(),
                                          parameters[2].data(), mono);
  EXPECT_DOUBLE_EQ(stereo_layout[0], mono[0]);
  EXPECT_DOUBLE_EQ(stereo_layout[1], mono[1]);
  EXPECT_EQ(stereo_layout[2], 0.0);
}

TEST(ReprojectionCostTest, MonoJacobiansMatchNumericDerivatives) {
  const Eigen::Vector2d left(170.0, 100.0);
  ExpectJacobiansMatchNumeric<MonoReprojectionCost, 2, 4, 3, 3>(
      MonoReprojectionCost::Create(left, kIntrinsics), new MonoReprojectionCost(left, kIntrinsics),
      PoseAndPoint());
}

TEST(ReprojectionCostTest, ZeroAtTheTruePose) {
  const Eigen::Vector3d point(0.3, -0.2, 2.5);
  const Eigen::Vector2d left(kIntrinsics.f * 0.3 / 2.5 + kIntrinsics.cx,
                             kIntrinsics.f * -0.2 / 2.5 + kIntrinsics.cy);
  const double right_x = kIntrinsics.f * (0.3 - 0.144) / 2.5 + kIntrinsics.cx;
  StereoReprojectionCost cost(left, right_x, kIntrinsics, 8.0);
  const double rotation[4] = {0, 0, 0, 1}, translation[3] = {0, 0, 0}, unchanged[3] = {0, 0, 0};
  double residuals[3];
  cost(rotation, translation, point.data(), unchanged, residuals);
  for (double r : residuals) EXPECT_NEAR(r, 0.0, 1e-12);
}

// A disparity measured with a bias is explained exactly by the correction change that takes the
// bias off: the residual vanishes when the change equals the bias (disparity_correction.h).
TEST(ReprojectionCostTest, ACorrectionChangeTakesABiasOffTheDisparity) {
  const Eigen::Vector3d point(0.3, -0.2, 2.5);
  const Eigen::Vector2d left(kIntrinsics.f * 0.3 / 2.5 + kIntrinsics.cx,
                             kIntrinsics.f * -0.2 / 2.5 + kIntrinsics.cy);
  const double true_right_x = kIntrinsics.f * (0.3 - 0.144) / 2.5 + kIntrinsics.cx;
  const DisparityCorrection bias{0.5, 0.003};
  // The measured right column: moved left by the bias (the disparity grows by it).
  const double measured_right_x =
      true_right_x - bias.BiasPx(true_right_x, kIntrinsics.f, kIntrinsics.cx);
  StereoReprojectionCost cost(left, measured_right_x, kIntrinsics, 8.0);
  const double rotation[4] = {0, 0, 0, 1}, translation[3] = {0, 0, 0};
  const double change[3] = {bias.offset_px, bias.yaw_rad, 0.0};
  double residuals[3];
  cost(rotation, translation, point.data(), change, residuals);
  // First order in the yaw: the gain is taken at the measured column, not the true one.
  EXPECT_NEAR(residuals[2], 0.0, 8.0 * 1e-3);
  const double none[3] = {0, 0, 0};
  cost(rotation, translation, point.data(), none, residuals);
  EXPECT_GT(std::abs(residuals[2]), 8.0 * 0.9);
}

// The generated head's stereo rig in the generated room: one shot, and the rig's rectifier.
struct RoomShot {
  RoomShot()
      : rig(sim::MakeRig(sim::RigOptions{})),
        rectifier(rig.left.camera, rig.right.camera,
                  rig.right.body_from_cam.Inverse() * rig.left.body_from_cam) {
    sim::RoomOptions room;
    room.texel_m = 0.006;
    const sim::World world = sim::MakeRoom(room);
    const Rigid3d body(RotationFromRollPitchYaw(0, 0.02, 0.4), Eigen::Vector3d(-0.5, -0.6, 1.45));
    Rng noise(1);
    shot = sim::RenderStereoShot(world, rig, body, sim::SensorModel{}, &noise);
  }
  sim::StereoRig rig;
  StereoRectifier rectifier;
  sim::StereoShot shot;
};

// Stereo matches' disparity errors (px) against the rendered depth, with the patch refinement
// of `refine_radius_px` (0: the correlation peak alone). `frame_out`, when given, receives the
// frame, built with `threads`.
std::vector<double> DisparityErrorsPx(int refine_radius_px, int* matches, size_t* features,
                                      int threads = 1, StereoFrame* frame_out = nullptr) {
  const RoomShot room;
  const cv::Mat& depth = room.shot.left_depth;
  const StereoRectifier& rectifier = room.rectifier;
  const auto extractor = CreateFeatureExtractor(DefaultFeatureSettings("harris_surf16"));
  StereoMatchOptions options;
  options.refine_patch_radius_px = refine_radius_px;
  options.threads = threads;
  const StereoFrame frame =
      BuildStereoFrame(room.shot.left, room.shot.right, *extractor, rectifier, options);
  if (frame_out) *frame_out = frame;
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

// The same frame, keypoint for keypoint: matches, points and the searches' counts.
void ExpectSameFrame(const StereoFrame& a, const StereoFrame& b) {
  ASSERT_EQ(a.left.size(), b.left.size());
  EXPECT_EQ(a.stereo_matches(), b.stereo_matches());
  for (const auto& [x, y] : {std::pair{a.stats.searched, b.stats.searched},
                             {a.stats.weak, b.stats.weak},
                             {a.stats.ambiguous, b.stats.ambiguous},
                             {a.stats.refine_rejected, b.stats.refine_rejected},
                             {a.stats.out_of_range, b.stats.out_of_range}}) {
    EXPECT_EQ(x, y);
  }
  for (size_t i = 0; i < a.left.size(); ++i) {
    EXPECT_EQ(std::isfinite(a.right_x_rect[i]), std::isfinite(b.right_x_rect[i]));
    if (std::isfinite(a.right_x_rect[i])) {
      EXPECT_EQ(a.right_x_rect[i], b.right_x_rect[i]) << "keypoint " << i;
      EXPECT_EQ(a.point_in_rect[i], b.point_in_rect[i]) << "keypoint " << i;
    }
  }
}

// Threads split the keypoints' searches (and extract beside rectifying): the frame is the same,
// match for match, as on one thread.
TEST(StereoFrameTest, ThreadsBuildTheSameFrame) {
  int matches = 0;
  size_t features = 0;
  StereoFrame one, three;
  DisparityErrorsPx(7, &matches, &features, 1, &one);
  DisparityErrorsPx(7, &matches, &features, 3, &three);
  EXPECT_GT(one.stereo_matches(), 500);
  ExpectSameFrame(one, three);
}

// Tracking searches the keypoints it matched, a keyframe the rest: searched in parts, in any
// order and overlapping, the frame is BuildStereoFrame's, value for value; before it is
// complete, the keypoints not searched have no match.
TEST(StereoFrameTest, AFrameSearchedInPartsIsTheFrameSearchedWhole) {
  const RoomShot room;
  const auto extractor = CreateFeatureExtractor(DefaultFeatureSettings("harris_surf16"));
  StereoMatchOptions options;
  options.threads = 2;
  const StereoFrame whole =
      BuildStereoFrame(room.shot.left, room.shot.right, *extractor, room.rectifier, options);
  StereoFrameSearch search(room.shot.left, room.shot.right, *extractor, room.rectifier, options);
  const int n = static_cast<int>(search.frame().left.size());
  ASSERT_GT(n, 500);
  EXPECT_EQ(search.frame().stats.searched, 0);
  std::vector<int> thirds, backwards;
  for (int i = 0; i < n; i += 3) thirds.push_back(i);
  for (int i = n / 2; i >= 0; i -= 2) backwards.push_back(i);
  search.Search(thirds);
  search.Search(backwards);
  for (int i = 0; i < n; ++i) {
    const bool searched = i % 3 == 0 || (i <= n / 2 && (n / 2 - i) % 2 == 0);
    const bool expected = searched && whole.HasDepth(i);
    EXPECT_EQ(search.frame().HasDepth(i), expected) << "keypoint " << i;
  }
  EXPECT_LT(search.frame().stereo_matches(), whole.stereo_matches());
  const StereoFrame parts = std::move(search).Complete();
  EXPECT_GT(whole.stereo_matches(), 500);
  ExpectSameFrame(whole, parts);
}

// A map build's preparing thread runs every search ahead, before the mapping thread knows the
// rig's disparity correction: with the correction set after, the frame searched in parts (and
// its counts: only the keypoints asked for) is the lazily searched one, value for value.
TEST(StereoFrameTest, SearchesRunAheadGiveTheFrameSearchedWhenAskedWithTheCorrectionSetAfter) {
  const RoomShot room;
  const auto extractor = CreateFeatureExtractor(DefaultFeatureSettings("harris_surf16"));
  StereoMatchOptions options;
  options.threads = 2;
  const DisparityCorrection correction{0.3, 0.001};  // px, rad
  const StereoFrame whole = BuildStereoFrame(room.shot.left, room.shot.right, *extractor,
                                             room.rectifier, options, correction);
  StereoFrameSearch lazy(room.shot.left, room.shot.right, *extractor, room.rectifier, options);
  StereoFrameSearch ahead(room.shot.left, room.shot.right, *extractor, room.rectifier, options);
  ahead.SearchAhead();
  EXPECT_EQ(ahead.frame().stats.searched, 0);  // Nothing counted until asked for.
  EXPECT_EQ(ahead.frame().stereo_matches(), 0);
  lazy.SetCorrection(correction);
  ahead.SetCorrection(correction);
  std::vector<int> odd;
  for (int i = 1; i < static_cast<int>(ahead.frame().left.size()); i += 2) odd.push_back(i);
  lazy.Search(odd);
  ahead.Search(odd);
  ExpectSameFrame(lazy.frame(), ahead.frame());
  EXPECT_EQ(lazy.searched(), ahead.searched());
  const StereoFrame completed = std::move(ahead).Complete();
  EXPECT_GT(whole.stereo_matches(), 500);
  ExpectSameFrame(whole, completed);
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

// The `drive` sequence's street seen by its car rig (KITTI's geometry), whose right camera is
// really turned by `right_yaw_error_deg` against its calibration, rendered at one sample a pixel.
class DriveScene {
 public:
  explicit DriveScene(double right_yaw_error_deg)
      : spec_(sim::MakeSequenceSpec("drive", 1)),
        rig_(sim::MakeRig(sim::CarRig({}))),
        world_(sim::MakeStreet(spec_.room)),
        rectifier_(rig_.left.camera, rig_.right.camera,
                   rig_.right.body_from_cam.Inverse() * rig_.left.body_from_cam),
        right_error_(Eigen::Quaterniond(Eigen::AngleAxisd(right_yaw_error_deg * M_PI / 180,
                                                          Eigen::Vector3d::UnitY())),
                     Eigen::Vector3d::Zero()) {}

  // The left image (with its depth) and the right one at `time_s`.
  void Render(double time_s, cv::Mat* left, cv::Mat* right, cv::Mat* depth = nullptr) const {
    const Rigid3d body = spec_.path.WorldFromBody(time_s);
    const sim::Renderer left_renderer(rig_.left.camera, 1), right_renderer(rig_.right.camera, 1);
    sim::SensorModel sensor;
    Rng noise(static_cast<uint64_t>(time_s * 1000) + 1);
    *left = sensor.Capture(
        left_renderer.RenderRadiance(world_, body * rig_.left.body_from_cam, time_s, depth),
        &noise);
    *right = sensor.Capture(right_renderer.RenderRadiance(
                                world_, body * rig_.right.body_from_cam * right_error_, time_s),
                            &noise);
  }
  // The left camera at `time_s` in the frame of the left camera at time 0 (the rectified frame:
  // the rig is rectified as built).
  Rigid3d CamFromFirst(double time_s) const {
    return (spec_.path.WorldFromBody(time_s) * rig_.left.body_from_cam).Inverse() *
           spec_.path.WorldFromBody(0.0) * rig_.left.body_from_cam;
  }
  const StereoRectifier& rectifier() const { return rectifier_; }

 private:
  sim::SequenceSpec spec_;
  sim::StereoRig rig_;
  sim::World world_;
  StereoRectifier rectifier_;
  Rigid3d right_error_;
};

// Disparities of a rig whose right camera is turned by 0.1 deg are 1.25-2.2 px too large; the
// correction for that yaw takes it off, at build time or afterwards (CorrectStereoFrame).
TEST(StereoFrameTest, TheRigsDisparityCorrectionTakesItsBiasOff) {
  const DriveScene scene(0.1);
  cv::Mat left, right, depth;
  scene.Render(0.0, &left, &right, &depth);
  const auto extractor = CreateFeatureExtractor(
      FeatureSettingsForImage(DefaultFeatureSettings("harris_surf16"), left.cols, left.rows));
  const double fb = scene.rectifier().rectified_camera().fx() * scene.rectifier().baseline_m();
  // Median signed disparity error against the rendered depth, px.
  const auto median_error_px = [&](const StereoFrame& frame) {
    std::vector<double> errors;
    for (size_t i = 0; i < frame.left.size(); ++i) {
      const Eigen::Vector2f& px = frame.left.keypoints[i].pixel;
      const float z = depth.at<float>(std::lround(px.y()), std::lround(px.x()));
      if (frame.HasDepth(i) && z > 0) errors.push_back(fb / frame.point_in_rect[i].z() - fb / z);
    }
    std::sort(errors.begin(), errors.end());
    return errors[errors.size() / 2];
  };
  const DisparityCorrection yaw{0.0, 0.1 * M_PI / 180};
  const StereoMatchOptions options;
  const StereoFrame trusting =
      BuildStereoFrame(left, right, *extractor, scene.rectifier(), options);
  const StereoFrame corrected =
      BuildStereoFrame(left, right, *extractor, scene.rectifier(), options, yaw);
  StereoFrame corrected_later = trusting;
  CorrectStereoFrame(yaw, scene.rectifier(), options, &corrected_later);
  std::printf("median disparity error: %.3f px trusting the calibration, %.3f px corrected\n",
              median_error_px(trusting), median_error_px(corrected));
  EXPECT_GT(median_error_px(trusting), 1.2);
  EXPECT_LT(std::abs(median_error_px(corrected)), 0.1);
  EXPECT_NEAR(median_error_px(corrected_later), median_error_px(corrected), 1e-9);
  EXPECT_EQ(corrected_later.stereo_matches(), corrected.stereo_matches());
}

// A frame whose prediction is 10 deg off (a car's frame skipped, the second frame of a sequence
// whose motion nothing predicts: KITTI 01's even frames lost tracking on 12 of 26 frames): every
// landmark projects 125 px from its keypoint, twice the search radius, and the last keyframe's
// landmarks matched by descriptor alone find the frame.
TEST(FrameTrackerTest, AFrameFarFromItsPredictionIsFoundByDescriptorsAlone) {
  const DriveScene scene(0.0);
  const auto extractor = CreateFeatureExtractor(
      FeatureSettingsForImage(DefaultFeatureSettings("harris_surf16"), 1241, 376));
  const StereoMatchOptions options;
  cv::Mat left, right;
  scene.Render(0.0, &left, &right);
  SlamState state;
  AddKeyframe(&state, 0, BuildStereoFrame(left, right, *extractor, scene.rectifier(), options),
              Rigid3d::Identity(), {});
  scene.Render(0.6, &left, &right);
  StereoFrameSearch frame(left, right, *extractor, scene.rectifier(), options);
  const Camera& rect = scene.rectifier().rectified_camera();
  const RectifiedIntrinsics intrinsics{rect.fx(), rect.cx(), rect.cy(),
                                       scene.rectifier().baseline_m()};
  const FrameTracker tracker(TrackingOptions{}, ViewOf(scene.rectifier()), intrinsics, 8.0);
  const Rigid3d truth = scene.CamFromFirst(0.6);
  const Rigid3d turned(
      Eigen::Quaterniond(Eigen::AngleAxisd(10 * M_PI / 180, Eigen::Vector3d::UnitY())),
      Eigen::Vector3d::Zero());
  const TrackResult track =
      tracker.Track(state, &frame, turned * truth, RecentLandmarks(state, 10), 1);
  ASSERT_TRUE(track.success);
  const double error_m = (CameraCenter(track.cam_from_world) - CameraCenter(truth)).norm();
  std::printf("%zu landmarks tracked, %.1f cm from the truth %.2f m away\n", track.tracked.size(),
              100 * error_m, CameraCenter(truth).norm());
  EXPECT_GT(track.tracked.size(), 100u);
  EXPECT_LT(error_m, 0.05);
  // Only the keypoints matched to landmarks were searched in the right image.
  EXPECT_LT(frame.frame().stats.searched, static_cast<int>(frame.frame().left.size()));
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
  const Map map =
      BuildMap(dataset, builder_options, {"vo", 0, "test", "test", ""}, &stats, &estimate);
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

// Frame by frame (mapping over the link answers every frame with it), the builder's progress is
// its trajectory's last pose and its keyframe count so far.
TEST(MapBuilderProgressTest, EachFrameReportsItsPoseAndTheMapSoFar) {
  TempDir dir;
  const Dataset dataset = RenderShort("map_square", 20, dir);
  const DatasetSource source(dataset);
  MapBuilder builder(source.left_camera(), source.right_camera(), source.right_from_left(), {});
  int keyframes_before = 0;
  size_t memory_before = 0;
  for (int i = 0; i < source.size(); ++i) {
    const StereoImages frame = source.Read(i);
    builder.AddFrame(frame.timestamp_ns, frame.left_raw, frame.right_raw);
    const MapBuilderProgress progress = builder.Progress();
    EXPECT_EQ(progress.frames, i + 1);
    EXPECT_TRUE(progress.last_tracked) << "frame " << i;
    EXPECT_GE(progress.keyframes, std::max(1, keyframes_before));
    keyframes_before = progress.keyframes;
    const Rigid3d last =
        builder.FrameTrajectory().back().pose;  // A copy: the trajectory is a temporary.
    EXPECT_LT((progress.map_from_cam.translation - last.translation).norm(), 1e-9) << "frame " << i;
    EXPECT_LT(progress.map_from_cam.rotation.angularDistance(last.rotation), 1e-9);
    if (i > 0) {
      EXPECT_GT(progress.tracked, 50) << "frame " << i;
    }
    // Every frame is kept while the rig's disparity bias is being estimated: memory only grows.
    EXPECT_GT(builder.MemoryBytes(), memory_before) << "frame " << i;
    memory_before = builder.MemoryBytes();
  }
  EXPECT_GT(memory_before, size_t{20} * 600 * 64);  // 20 frames of 600 16-float descriptors.
  EXPECT_GE(keyframes_before, 2);
  EXPECT_GT(builder.Progress().landmarks, 500);
  EXPECT_EQ(builder.Progress().tracking_failures, 0);
  // The map so far for drawing: every keyframe, the first at the map's origin; points decimated.
  const MapSoFar view = builder.MapSoFarView(100);
  ASSERT_EQ(static_cast<int>(view.keyframe_centres.size()), keyframes_before);
  EXPECT_LT(view.keyframe_centres[0].norm(), 1e-9);
  EXPECT_EQ(view.total_points, builder.Progress().landmarks);
  EXPECT_LE(view.points.size(), 100u);
  EXPECT_GE(view.points.size(), 50u);
}

// A run longer than global_ba_max_keyframes is adjusted at the end piece by piece, each piece
// with the keyframes around it held: as accurate as the whole adjustment.
TEST(MapBuilderGlobalAdjustmentTest, PiecesAreAsAccurateAsTheWholeRun) {
  TempDir dir;
  const Dataset dataset = RenderShort("map_square", 150, dir);
  const Trajectory truth = ReadTum(dataset.root + "/groundtruth_map.tum");
  const auto worst_error_m = [&](int max_keyframes, MapBuildStats* stats) {
    DatasetMappingOptions options;
    options.builder.loop_closure.enabled = false;
    options.builder.global_ba_max_keyframes = max_keyframes;
    Trajectory estimate;
    BuildMap(dataset, options, {"pieces", 0, "test", "test", ""}, stats, &estimate);
    EXPECT_EQ(estimate.size(), truth.size());
    double worst_m = 0;
    for (size_t i = 0; i < std::min(truth.size(), estimate.size()); ++i) {
      worst_m =
          std::max(worst_m, (estimate[i].pose.translation - truth[i].pose.translation).norm());
    }
    return worst_m;
  };
  MapBuildStats whole, pieces;
  const double whole_m = worst_error_m(1000, &whole), pieces_m = worst_error_m(6, &pieces);
  std::printf("%d keyframes: worst error %.2f cm adjusted whole, %.2f cm in %d pieces\n",
              whole.keyframes, 100 * whole_m, 100 * pieces_m, pieces.global_ba_pieces);
  EXPECT_EQ(whole.global_ba_pieces, 1);
  ASSERT_GE(whole.keyframes, 13);
  EXPECT_EQ(pieces.global_ba_pieces, (whole.keyframes - 1 + 5) / 6);
  EXPECT_LT(whole_m, 0.02);
  EXPECT_LT(pieces_m, whole_m + 0.003);
}

// MapBuilderOptions::threads splits a frame's work, reads and prepares the next frame beside this
// one's mapping: the map is the same, keyframe for keyframe and point for point.
TEST(MapBuilderThreadsTest, TwoThreadsBuildTheSameMapAsOne) {
  TempDir dir;
  const Dataset dataset = RenderShort("map_square", 40, dir);
  std::vector<Map> maps;
  std::vector<MapBuildStats> stats(2);
  for (int threads : {1, 2}) {
    DatasetMappingOptions options;
    options.builder.threads = threads;
    // The rig's disparity correction estimated at frame 20, while frame 21 is prepared beside
    // it on two threads: that frame's searches take the new correction off all the same.
    options.builder.disparity_calibration.max_frames = 20;
    options.builder.disparity_calibration.min_travel_baselines = 0.1;
    maps.push_back(BuildMap(dataset, options, {"t", 0, "test", "test", ""}, &stats[threads - 1]));
  }
  EXPECT_GE(stats[1].calibration_passes, 1);
  ASSERT_GE(maps[0].keyframes.size(), 3u);
  ASSERT_EQ(maps[0].keyframes.size(), maps[1].keyframes.size());
  ASSERT_EQ(maps[0].points.size(), maps[1].points.size());
  for (size_t k = 0; k < maps[0].keyframes.size(); ++k) {
    EXPECT_EQ(maps[0].keyframes[k].map_from_cam.translation,
              maps[1].keyframes[k].map_from_cam.translation)
        << "keyframe " << k;
  }
  for (size_t i = 0; i < maps[0].points.size(); ++i) {
    ASSERT_EQ(maps[0].points[i].position_in_map, maps[1].points[i].position_in_map)
        << "point " << i;
  }
  EXPECT_EQ(stats[0].observations, stats[1].observations);
}

TEST(MapBuilderInputTest, MonocularDatasetsAreRefused) {
  TempDir dir;
  Dataset dataset = RenderShort("straight", 2, dir);
  dataset.right.reset();
  EXPECT_THROW(BuildMap(dataset, DatasetMappingOptions{}, {"m", 0, "", "", ""}, nullptr),
               InputError);
}

TEST(MapBuilderInputTest, ASingleStereoPairIsAMapOfItsStereoPoints) {
  // A robot that stands still maps from one keyframe: its stereo points have measured depth.
  TempDir dir;
  const Dataset dataset = RenderShort("map_square", 1, dir);
  MapBuildStats stats;
  const Map map =
      BuildMap(dataset, DatasetMappingOptions{}, {"one", 0, "test", "test", ""}, &stats);
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
    keyframe.cam_from_world =
        Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(-0.1 * k, 0, 0));
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
  const Map map =
      AssembleMap(state, Camera(320, 240, 160, 160, 159.5, 119.5),
                  DefaultFeatureSettings("harris_surf16"), {"m", 0, "", "", ""},
                  Rigid3d::Identity(), Rigid3d::Identity(), kIntrinsics, AssemblyOptions{}, &stats);
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
