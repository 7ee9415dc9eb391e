// Microbenchmarks of the localization hot kernels (Google Benchmark). Run:
//   build/core/localization/localization_benchmark --benchmark_counters_tabular=true
// Speed is measured here, never asserted in tests. Inputs are synthetic and deterministic:
// a textured random image for the feature extractor, a synthetic map and exact projections
// for the matcher and the solvers.

#include <benchmark/benchmark.h>

#include <opencv2/imgproc.hpp>

#include "core/estimators/p3p.h"
#include "core/estimators/pnp_ransac.h"
#include "core/estimators/pose_refinement.h"
#include "core/features/features.h"
#include "core/features/harris_surf16.h"
#include "core/image/image_codec.h"
#include "core/localization/localizability.h"
#include "core/localization/localizer.h"
#include "core/localization/map_matching.h"
#include "core/localization/pose_tracker.h"
#include "core/localization/visibility_predictor.h"
#include "core/map/synthetic_map.h"
#include "core/util/memory.h"
#include "core/util/random.h"

namespace visloc {
namespace {

// The first left image of a real recording in VISLOC_REAL_DATA (../shared/real), or an empty
// image when it is not there: real frames have far fewer corner candidates than the textured
// image, in clusters, so the detector's selection costs differently on them.
cv::Mat RealImage(const std::string& recording) {
  const std::string dir = std::string(VISLOC_REAL_DATA) + "/" + recording;
  for (const std::string& path :
       {dir + "/mav0/cam0/data/1403636584763555584.png", dir + "/image_0/000000.png"}) {
    std::string why;
    cv::Mat image = image::ReadGrey(path, &why);
    if (!image.empty()) return image;
  }
  return cv::Mat();
}

// Blurred noise with a little structure at several scales: corners everywhere, like a
// textured indoor scene, deterministic in the seed.
cv::Mat TexturedImage(int width, int height) {
  cv::RNG rng(7);
  cv::Mat image(height, width, CV_8UC1), fine(height, width, CV_8UC1),
      coarse(height / 8, width / 8, CV_8UC1);
  rng.fill(fine, cv::RNG::UNIFORM, 0, 255);
  rng.fill(coarse, cv::RNG::UNIFORM, 0, 255);
  cv::GaussianBlur(fine, fine, cv::Size(), 1.5);
  cv::resize(coarse, coarse, image.size(), 0, 0, cv::INTER_NEAREST);
  cv::addWeighted(fine, 0.5, coarse, 0.5, 0, image);
  return image;
}

// Extraction as a map is built (all scales, second argument 0) and as a localization session
// runs it (the finest scale only, second argument 1).
HarrisSurf16Options ExtractorOptions(bool finest_scale_only) {
  HarrisSurf16Options options;
  if (finest_scale_only) options.scales_px.resize(1);
  return options;
}

void BM_ExtractHarrisSurf16(benchmark::State& state) {
  const cv::Mat image =
      TexturedImage(static_cast<int>(state.range(0)), static_cast<int>(state.range(0)) * 3 / 4);
  const HarrisSurf16Extractor extractor(ExtractorOptions(state.range(1) == 1));
  size_t features = 0;
  for (auto _ : state) features = extractor.Extract(image).size();
  state.counters["features"] = static_cast<double>(features);
}
BENCHMARK(BM_ExtractHarrisSurf16)->ArgsProduct({{320, 640}, {0, 1}})->Unit(benchmark::kMillisecond);

// The two halves of extraction apart: detection, and description of the detected corners.
void BM_DetectHarrisSurf16(benchmark::State& state) {
  const cv::Mat image =
      TexturedImage(static_cast<int>(state.range(0)), static_cast<int>(state.range(0)) * 3 / 4);
  const HarrisSurf16Extractor extractor(ExtractorOptions(state.range(1) == 1));
  for (auto _ : state) benchmark::DoNotOptimize(extractor.Detect(image));
}
BENCHMARK(BM_DetectHarrisSurf16)->ArgsProduct({{320, 640}, {0, 1}})->Unit(benchmark::kMillisecond);

// Detection as a session runs it (finest scale) on real frames: EuRoC MH_01 at 752x480, KITTI 01
// at 1241x376.
void BM_DetectRealFrame(benchmark::State& state) {
  const cv::Mat image = RealImage(state.range(0) == 0 ? "euroc_mh01_moving" : "kitti01_first51");
  if (image.empty()) {
    state.SkipWithError("no real recordings (VISLOC_REAL_DATA)");
    return;
  }
  const HarrisSurf16Extractor extractor(ExtractorOptions(true));
  int detected = 0;
  for (auto _ : state) benchmark::DoNotOptimize(extractor.Detect(image, &detected));
  state.counters["candidates"] = detected;
  state.SetLabel(std::to_string(image.cols) + "x" + std::to_string(image.rows));
}
BENCHMARK(BM_DetectRealFrame)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// Extraction at every scale with the corner count for the image size, as a map build and a
// relocalization run it, on the real MH_01 frame (752x480: 1301 corners).
void BM_ExtractRealFrameAllScales(benchmark::State& state) {
  const cv::Mat image = RealImage("euroc_mh01_moving");
  if (image.empty()) {
    state.SkipWithError("no real recordings (VISLOC_REAL_DATA)");
    return;
  }
  HarrisSurf16Options options;
  options.max_features = FeatureCountForImage(options.max_features, image.cols, image.rows);
  const HarrisSurf16Extractor extractor(options);
  size_t features = 0;
  for (auto _ : state) features = extractor.Extract(image).size();
  state.counters["features"] = static_cast<double>(features);
}
BENCHMARK(BM_ExtractRealFrameAllScales)->Unit(benchmark::kMillisecond);

void BM_DescribeHarrisSurf16(benchmark::State& state) {
  const cv::Mat image =
      TexturedImage(static_cast<int>(state.range(0)), static_cast<int>(state.range(0)) * 3 / 4);
  const HarrisSurf16Extractor extractor(ExtractorOptions(state.range(1) == 1));
  const std::vector<Keypoint> keypoints = extractor.Detect(image);
  for (auto _ : state) benchmark::DoNotOptimize(extractor.Describe(image, keypoints));
  state.counters["features"] = static_cast<double>(keypoints.size());
}
BENCHMARK(BM_DescribeHarrisSurf16)
    ->ArgsProduct({{320, 640}, {0, 1}})
    ->Unit(benchmark::kMillisecond);

void BM_OrbReference(benchmark::State& state) {
  const cv::Mat image =
      TexturedImage(static_cast<int>(state.range(0)), static_cast<int>(state.range(0)) * 3 / 4);
  const auto extractor = CreateFeatureExtractor(DefaultFeatureSettings("orb"));
  for (auto _ : state) benchmark::DoNotOptimize(extractor->Extract(image));
}
BENCHMARK(BM_OrbReference)->Arg(320)->Arg(640)->Unit(benchmark::kMillisecond);

void BM_DescriptorDistance(benchmark::State& state) {
  const bool binary = state.range(0) == 1;
  cv::Mat a(1000, binary ? 32 : 16, binary ? CV_8U : CV_32F);
  cv::randu(a, 0, binary ? 255 : 1);
  int row = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(DescriptorDistance(a, row, a, (row + 1) % 1000));
    row = (row + 7) % 1000;
  }
  state.SetLabel(binary ? "hamming 256 bit" : "L2 16 float");
}
BENCHMARK(BM_DescriptorDistance)->Arg(0)->Arg(1);

struct Scene {
  std::shared_ptr<const LocalizationMap> map;
  Rigid3d cam_from_map;
  FeatureSet features;
};

// A synthetic map and a view of it with keypoints at the exact projections.
const Scene& TestScene() {
  static const Scene scene = [] {
    SyntheticMapOptions options;
    options.keyframes = 60;
    options.points = 10000;
    Scene s;
    s.map = std::make_shared<const LocalizationMap>(MakeSyntheticMap(options));
    s.cam_from_map = s.map->map().keyframes[20].map_from_cam.Inverse();
    Rng rng(3);
    for (uint32_t j : s.map->VisiblePoints(20)) {
      Eigen::Vector2d pixel;
      if (!s.map->map().camera.Project(s.cam_from_map * s.map->map().points[j].position_in_map,
                                       &pixel)) {
        continue;
      }
      pixel += Eigen::Vector2d(rng.Normal(0, 0.3), rng.Normal(0, 0.3));
      s.features.keypoints.push_back({pixel.cast<float>(), 1.2f, 1.0f});
      s.features.descriptors.push_back(s.map->map().descriptors.row(static_cast<int>(j)));
    }
    return s;
  }();
  return scene;
}

void BM_PredictVisibility(benchmark::State& state) {
  const Scene& s = TestScene();
  const VisibilityPredictor predictor(*s.map, VisibilityOptions{});
  size_t predicted = 0;
  for (auto _ : state) predicted = predictor.Predict(s.cam_from_map.Inverse()).size();
  state.counters["predicted"] = static_cast<double>(predicted);
}
BENCHMARK(BM_PredictVisibility);

void BM_ProjectAndMatch(benchmark::State& state) {
  const Scene& s = TestScene();
  const QueryFrame frame(s.features, s.map->map().camera);
  std::vector<uint32_t> points;
  for (uint32_t j : s.map->VisiblePoints(20)) points.push_back(j);
  size_t matches = 0;
  for (auto _ : state) {
    const auto projected =
        ProjectPoints(s.map->AllPoints(), s.map->map().camera, s.cam_from_map, points);
    matches =
        MatchProjected(s.map->AllPoints(), projected, frame, 15.0, DescriptorMatchOptions{}).size();
  }
  state.counters["points"] = static_cast<double>(points.size());
  state.counters["matches"] = static_cast<double>(matches);
}
BENCHMARK(BM_ProjectAndMatch);

// Relocalization's candidate matching: every keypoint of the view against every point its
// keyframe sees, nearest two with the ratio test (MatchByDescriptor).
void BM_MatchByDescriptor(benchmark::State& state) {
  const Scene& s = TestScene();
  const QueryFrame frame(s.features, s.map->map().camera);
  const std::vector<uint32_t> points(s.map->VisiblePoints(20).begin(),
                                     s.map->VisiblePoints(20).end());
  size_t matches = 0;
  for (auto _ : state) {
    matches = MatchByDescriptor(s.map->AllPoints(), points, frame, DescriptorMatchOptions{}).size();
  }
  state.counters["keypoints"] = static_cast<double>(frame.size());
  state.counters["points"] = static_cast<double>(points.size());
  state.counters["matches"] = static_cast<double>(matches);
}
BENCHMARK(BM_MatchByDescriptor)->Unit(benchmark::kMicrosecond);

std::vector<PoseObservation> Observations(double outlier_fraction) {
  const Scene& s = TestScene();
  const QueryFrame frame(s.features, s.map->map().camera);
  std::vector<PoseObservation> observations;
  Rng rng(5);
  size_t i = 0;
  for (uint32_t j : s.map->VisiblePoints(20)) {
    if (i >= frame.size()) break;
    PoseObservation o;
    o.point_in_world = s.map->map().points[j].position_in_map;
    o.normalized = frame.normalized(static_cast<int>(i++));
    if (rng.Uniform01() < outlier_fraction) o.normalized += Eigen::Vector2d(0.2, -0.1);
    observations.push_back(o);
  }
  return observations;
}

void BM_SolveP3P(benchmark::State& state) {
  const auto observations = Observations(0.0);
  const std::array<Eigen::Vector3d, 3> points = {observations[0].point_in_world,
                                                 observations[10].point_in_world,
                                                 observations[20].point_in_world};
  const std::array<Eigen::Vector2d, 3> bearings = {
      observations[0].normalized, observations[10].normalized, observations[20].normalized};
  for (auto _ : state) benchmark::DoNotOptimize(SolveP3P(points, bearings));
}
BENCHMARK(BM_SolveP3P);

void BM_PnpRansac(benchmark::State& state) {
  const auto observations = Observations(state.range(0) / 100.0);
  PnpRansacOptions options;
  options.refine.focal_px = 160.0;
  int iterations = 0;
  for (auto _ : state) iterations = SolvePnpRansac(observations, options).stats.iterations;
  state.counters["observations"] = static_cast<double>(observations.size());
  state.counters["ransac_iterations"] = iterations;
  state.SetLabel(std::to_string(state.range(0)) + "% outliers");
}
BENCHMARK(BM_PnpRansac)->Arg(5)->Arg(30)->Arg(60)->Unit(benchmark::kMicrosecond);

// Levenberg-Marquardt on all of a frame's inliers from a pose a few centimetres off: the last
// step of every tracked frame (and of every RANSAC winner).
void BM_RefinePose(benchmark::State& state) {
  const auto observations = Observations(0.0);
  PoseRefineOptions options;
  options.focal_px = 160.0;
  const Rigid3d truth = SolvePnpRansac(observations, PnpRansacOptions()).cam_from_world;
  const Rigid3d start(truth.rotation, truth.translation + Eigen::Vector3d(0.03, -0.02, 0.04));
  PoseRefineStats stats;
  for (auto _ : state) benchmark::DoNotOptimize(RefinePose(start, observations, options, &stats));
  state.counters["observations"] = static_cast<double>(observations.size());
  state.counters["lm_iterations"] = stats.iterations;
}
BENCHMARK(BM_RefinePose)->Unit(benchmark::kMicrosecond);

// Global relocalization against map size: synthetic maps of N keyframes (25 N points, each seen
// by 4 keyframes, a 512-word vocabulary), one query view near keyframe N/2 with 100 clutter
// keypoints. Retrieval goes through the inverted index, so its cost follows the keyframes that
// share words with the query, and verification is a fixed number of candidates.
void BM_RelocalizeScaling(benchmark::State& state) {
  const int keyframes = static_cast<int>(state.range(0));
  SyntheticMapOptions options;
  options.keyframes = keyframes;
  options.points = 25 * keyframes;
  options.vocabulary_depth = 3;
  options.appearance_from_descriptors = true;
  const auto map = std::make_shared<const LocalizationMap>(MakeSyntheticMap(options));
  const int k = keyframes / 2;
  const Rigid3d cam_from_map = map->map().keyframes[k].map_from_cam.Inverse();
  FeatureSet features;
  Rng rng(11);
  for (uint32_t j : map->VisiblePoints(k)) {
    Eigen::Vector2d pixel;
    if (!map->map().camera.Project(cam_from_map * map->map().points[j].position_in_map, &pixel) ||
        !map->map().camera.IsInImage(pixel)) {
      continue;
    }
    features.keypoints.push_back({pixel.cast<float>(), 1.2f, 1.0f});
    features.descriptors.push_back(map->map().descriptors.row(static_cast<int>(j)));
  }
  for (int c = 0; c < 100; ++c) {
    features.keypoints.push_back(
        {Eigen::Vector2f(rng.Uniform(0, 319), rng.Uniform(0, 239)), 1.2f, 1.0f});
    cv::Mat descriptor(1, 16, CV_32F);
    cv::randu(descriptor, -1, 1);
    features.descriptors.push_back(descriptor);
  }
  const QueryFrame frame(features, map->map().camera);
  const QueryPipeline pipeline(map, map->map().camera, LocalizerOptions{});
  bool found = false;
  for (auto _ : state) found = pipeline.relocalizer().Relocalize(frame).success;
  state.counters["found"] = found;
  state.counters["points"] = static_cast<double>(map->point_count());
  state.counters["memory_MiB"] = map->MemoryBytes() / (1024.0 * 1024.0);
}
BENCHMARK(BM_RelocalizeScaling)->Arg(100)->Arg(1000)->Arg(10000)->Unit(benchmark::kMillisecond);

// The localizability grid (`visloc map localizability`) of a building floor covered in lanes:
// state.range(0) keyframes 0.15 m apart along 100 m lanes 3 m apart, 500 observations each (the
// generated square's map has 535), a cell of 0.5 m and 8 headings, on 2 threads.
void BM_LocalizabilityGrid(benchmark::State& state) {
  SyntheticMapOptions options;
  options.keyframes = static_cast<int>(state.range(0));
  options.points = options.keyframes * 125;
  options.lane_length_m = 100.0;
  options.appearance = false;
  const LocalizationMap map(MakeSyntheticMap(options));
  LocalizabilityOptions grid_options;
  grid_options.threads = 2;
  LocalizabilityStats stats;
  for (auto _ : state) {
    benchmark::DoNotOptimize(ComputeLocalizability(map, Rigid3d::Identity(), grid_options, &stats));
  }
  state.counters["poses"] = stats.poses;
  state.counters["good_poses"] = stats.good_poses;
}
BENCHMARK(BM_LocalizabilityGrid)
    ->Arg(1000)
    ->Arg(10000)
    ->Unit(benchmark::kSecond)
    ->UseRealTime()
    ->Iterations(1);

}  // namespace
}  // namespace visloc

// As in the server and the CLI: freed image buffers are reused, not returned to the kernel
// and faulted in again on the next frame, and OpenCV runs on the calling thread.
int main(int argc, char** argv) {
  visloc::KeepFreedMemoryForReuse();
  visloc::RunOpenCvOnCallingThread();
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
